"""The message types translators read and write, each named once: a type name and its encoding.

A translator declares these in `reads`, `outputs` and `replies`; the config check matches them
against what each route's transports carry. Families share them through this module, never
through each other's.
"""

from __future__ import annotations

from viewer_bridge.formats.foxglove.schema import (
    CAMERA_CALIBRATION,
    COMPRESSED_IMAGE,
    FRAME_TRANSFORMS,
    RAW_IMAGE,
    SCENE_UPDATE,
)
from viewer_bridge.formats.ign.schema import Package, type_name
from viewer_bridge.formats.rerun.schema import CHUNKS, RERUN
from viewer_bridge.lcmcodec.codecs import (
    CONTACT_RESULTS,
    DRAW,
    IMAGE_ARRAY,
    LINK_DATA,
    LOAD_ROBOT,
    POINT_CLOUD,
    VIEWER2_COMMS,
)
from viewer_bridge.transports.base import CARRIED_DEFINITION, CDR, LCM, PROTOBUF, MessageType
from viewer_bridge.transports.topic_types import ANY, EVERY

# Drake's LCM messages.
LOAD_TYPE = MessageType(LOAD_ROBOT.type_name, LCM)
DRAW_TYPE = MessageType(DRAW.type_name, LCM)
LINK_DATA_TYPE = MessageType(LINK_DATA.type_name, LCM)  # DRAKE_VIEWER_DEFORMABLE
CONTACT_TYPE = MessageType(CONTACT_RESULTS.type_name, LCM)
POINT_CLOUD_TYPE = MessageType(POINT_CLOUD.type_name, LCM)
IMAGE_ARRAY_TYPE = MessageType(IMAGE_ARRAY.type_name, LCM)  # DRAKE_RGBD_CAMERA_IMAGES*
# Any LCM type (`lcm_to_ros`: the channel's fingerprint says which), and the ROS 2 message it
# maps to: CDR of a type whose definition each instance's output carries (no installed package).
ANY_LCM_TYPE = MessageType("*", LCM)
LCM_AS_ROS_TYPE = MessageType("*", CDR, CARRIED_DEFINITION)
# Any generated LCM type's ROS 2 mapping, its name given per message by the transport (`ros_to_lcm`:
# the reverse routes); and any ROS 2 type at all (`ros_topic_to_lcm`: `ros_topics`).
ANY_ROS_TYPE = MessageType(ANY, CDR)
EVERY_ROS_TYPE = MessageType(EVERY, CDR)
# Director's tree viewer envelope (requests and responses alike).
ENVELOPE_TYPE = MessageType(VIEWER2_COMMS.type_name, LCM)
# Foxglove's protobuf schemas.
SCENE_UPDATE_TYPE = MessageType(SCENE_UPDATE, PROTOBUF)
FRAME_TRANSFORMS_TYPE = MessageType(FRAME_TRANSFORMS, PROTOBUF)
RAW_IMAGE_TYPE = MessageType(RAW_IMAGE, PROTOBUF)
COMPRESSED_IMAGE_TYPE = MessageType(COMPRESSED_IMAGE, PROTOBUF)
CAMERA_CALIBRATION_TYPE = MessageType(CAMERA_CALIBRATION, PROTOBUF)
# Rerun's chunks (Arrow record batches), whatever archetypes they hold.
RERUN_CHUNKS_TYPE = MessageType(CHUNKS, RERUN)


def ros_type(name: str) -> MessageType:
    """A ROS 2 message type (`geometry_msgs/msg/PoseArray`), carried as CDR."""
    return MessageType(name, CDR)


def ign_type(name: str, package: Package | None = None) -> MessageType:
    """An ign/gz protobuf message by its short name (`Pose_V`), which the ign transport spells in
    its package; or, with `package`, by its full name in that one (`ignition.msgs.Pose_V`)."""
    return MessageType(name if package is None else type_name(name, package), PROTOBUF)
