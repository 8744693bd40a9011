"""Any LCM type, as its ROS 2 mapping and back: `lcm_to_ros` and `ros_to_lcm`, with no
translator written per type.

A channel's type is the known type its message's first 8 bytes (the fingerprint) name, as
lcm-spy finds it, and may change from one message to the next. The known types are the router's
(`Shared.lcm_types`: the project's, Drake's, and the config's `lcm_types`); each maps to a ROS 2
message (`drake.lcmt_iiwa_status` -> `drake_lcm_msgs/msg/LcmtIiwaStatus`), written as CDR by the
type's own transcoder. The output's `MessageType` carries the mapped type's definition (its
`ros2msg` text and RIHS01 hash), so Zenoh, Foxglove and MCAP name the type with no installed
package; ROS 2 over DDS needs the interface built.

Outputs: the class declares one, "CDR of any type whose definition it carries", which the config
check matches against the destination. An instance adds an output per type as its channel
shows it (all on the route's destination name), as the camera translators add one per port:
the router finds an output by index and asks each for subscribers, so a lazy route's topic is
announced as soon as its channel's first message is seen, and translated once someone listens.

A fingerprint no known type has is held back (`unknown_type`), a type ROS 2 cannot say (a
recursive one) too (`refused_type`): counted on the channel, said once; the route's other
channels go on.

Back (`ros_to_lcm`): a message of a generated type (`drake_lcm_msgs/msg/LcmtIiwaCommand`), as
CDR from ROS 2 or Zenoh or as JSON from a Foxglove client, becomes the LCM bytes lcm-gen would
write, fingerprint first. The type is the message's own (`Received.message_type`: the transport
knows it per topic), so one route carries every channel whatever its type. A type that is no
generated LCM type is a `NotAnLcmType` naming the topic and the type, and bad bytes a
`DecodeError` naming the field: counted, and nothing is sent.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from viewer_bridge.errors import DecodeError, Held, NotAnLcmType
from viewer_bridge.lcmcodec.library import LcmType
from viewer_bridge.translators.base import Output, Outputs, Translator
from viewer_bridge.translators.types import ANY_LCM_TYPE, ANY_ROS_TYPE, LCM_AS_ROS_TYPE
from viewer_bridge.transports.base import JSON, Received
from viewer_bridge.transports.topic_types import ros_message_type


class LcmToRos(Translator):
    """Any known LCM type -> CDR of its ROS 2 mapping, one output per type the channel shows."""

    reads = (ANY_LCM_TYPE,)
    # What it may write (the config check); an instance's outputs are its channel's types, added as they appear.
    outputs: tuple[Output, ...] = (Output("", LCM_AS_ROS_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.outputs = ()
        self._by_fingerprint: dict[bytes, tuple[int, LcmType]] = {}

    def observe(self, message: Received) -> None:
        self._output(message)  # the topic appears with the channel, before anyone subscribes

    def translate(self, message: Received) -> Outputs:
        index, lcm_type = self._output(message)
        return [(index, lcm_type.to_cdr(message.data))]

    def quick(self, data: bytes) -> tuple[int, bytes] | None:
        found = self._by_fingerprint.get(data[:8])  # a type seen before: its output is there already
        return None if found is None else (found[0], found[1].to_cdr(data))

    def direct(self) -> tuple[int, Callable[[bytes], bytes | None]] | None:
        if len(self._by_fingerprint) != 1:  # a channel of several types: `quick` finds each one's output
            return None
        [(index, lcm_type)] = self._by_fingerprint.values()
        # Its transcoder's kept compiled programs, by size: a program compares the fingerprint, so
        # another type's message (or one of a size not kept) is None, and `quick` takes it.
        kept = lcm_type.transcoder.kept()
        return None if kept is None else (index, kept)

    def _output(self, message: Received) -> tuple[int, LcmType]:
        """The output of this message's type (added the first time the type is seen), and the type."""
        fingerprint = bytes(message.data[:8])
        found = self._by_fingerprint.get(fingerprint)
        if found is None:
            lcm_type = self.shared.lcm_types.type_of(message.data, message.channel)
            if lcm_type.ros_type is None:
                raise Held(
                    "refused_type", f"{lcm_type.full_name} cannot be a ROS 2 message: {lcm_type.refused}"
                )
            self.outputs = (*self.outputs, Output("", ros_message_type(lcm_type)))
            found = self._by_fingerprint[fingerprint] = (len(self.outputs) - 1, lcm_type)
        return found


class RosToLcm(Translator):
    """CDR (or JSON) of any generated LCM type's ROS 2 mapping -> the LCM message, on the route's
    destination channel. The message's type is its own, as its transport found it."""

    reads = (ANY_ROS_TYPE,)
    outputs = (Output("", ANY_LCM_TYPE),)
    commands = True  # it writes LCM channels that drive robots: only those the config allows, fresh

    def translate(self, message: Received) -> Outputs:
        lcm_type = self.lcm_type(message)
        assert message.message_type is not None  # lcm_type refused a message without one
        if message.message_type.encoding == JSON:
            return [(0, lcm_type.from_dict(parse_json(message.data, lcm_type.full_name)))]
        return [(0, lcm_type.from_cdr(message.data))]

    def lcm_type(self, message: Received) -> LcmType:
        """The LCM type whose ROS 2 mapping the message's type is; `NotAnLcmType` if none."""
        message_type = message.message_type
        if message_type is None:
            raise NotAnLcmType(
                f"{message.channel}: the transport gave no message type, so no LCM type is known"
            )
        lcm_type = self.shared.lcm_types.for_ros_type(message_type.name)
        if lcm_type is None:
            raise NotAnLcmType(
                f"{message.channel}: {message_type.name} is no generated LCM type (known: the *_lcm_msgs "
                "packages of the bridge's LCM types)"
            )
        return lcm_type


def parse_json(data: bytes, type_name: str) -> object:
    """A JSON message's value; text that is not JSON (or nested past Python's stack) is a DecodeError."""
    try:
        return json.loads(data)
    except (ValueError, RecursionError) as error:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
        offset = getattr(error, "pos", 0)
        reason = "nested too deeply" if isinstance(error, RecursionError) else f"not JSON: {error}"
        raise DecodeError(type_name, "<json>", offset, reason) from None
