"""Any ROS 2 topic onto LCM: `ros_topic_to_lcm`, the translator of `ros_topics` (`--ros-topics`).

A message's type is its topic's, as the transport found it in the graph; its CDR becomes the
LCM message of section 14's mapping of that type (docs/PROTOCOLS.md: `sensor_msgs/msg/JointState`
-> `sensor_msgs.JointState`, sequences with a length field, unsigned integers widened), written
by the type's compiled encoder (`viewer_bridge.lcmcodec.ros_types`), as `lcm-types generate
--ros-types` writes the `.lcm` files lcm-gen reads. A type with no definition here, or none LCM
can hold, is held (`refused_type`, said once per topic); bad bytes are a `DecodeError` naming
the field.

`exclusive`: each LCM channel carries one topic. A second topic whose messages would go on a
channel another already carries (the same topic over DDS and Zenoh, or a route of the config's
own) is held, the first kept (`channel_taken`, `viewer_bridge.router.runner`).
"""

from __future__ import annotations

from viewer_bridge.errors import Held
from viewer_bridge.lcmcodec.ros_types import RosTypesOnLcm
from viewer_bridge.translators.base import Output, Outputs, Translator
from viewer_bridge.translators.types import ANY_LCM_TYPE, EVERY_ROS_TYPE
from viewer_bridge.transports.base import Received


class RosTopicToLcm(Translator):
    """CDR of any ROS 2 type -> the LCM message of its section-14 mapping."""

    reads = (EVERY_ROS_TYPE,)
    outputs = (Output("", ANY_LCM_TYPE),)
    exclusive = True

    def translate(self, message: Received) -> Outputs:
        ros_type = message.message_type.name if message.message_type is not None else None
        if ros_type is None or ros_type == EVERY_ROS_TYPE.name:
            raise Held("refused_type", "the transport gave no message type: nothing to map onto LCM")
        encoder = self.shared.get(RosTypesOnLcm).encoder(ros_type)
        if isinstance(encoder, str):
            raise Held("refused_type", f"{ros_type} does not map onto LCM: {encoder}")
        return [(0, encoder.encode(message.data))]
