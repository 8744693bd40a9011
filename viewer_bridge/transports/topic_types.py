"""Which type a topic found in the graph is subscribed with: the one mechanism of the ROS 2 and
Zenoh transports for sources whose type is `*` (any generated LCM type), as ros1_bridge's dynamic
bridge subscribes each topic with the type its publishers announce.

A source of a named type takes a topic of that type. A source of type `*` takes a topic whose
announced type is the ROS 2 mapping of an LCM type the router knows (`Shared.lcm_types`), with
that type's definition (so Zenoh can name its hash and the ROS 2 transport build its interface); a
matching topic of any other type is said once in the log, with its type, and left alone.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterable
from typing import TYPE_CHECKING

from viewer_bridge.shared import Shared
from viewer_bridge.transports.base import CDR, Definition, MessageType

if TYPE_CHECKING:
    from viewer_bridge.lcmcodec.library import LcmType

log = logging.getLogger("viewer_bridge")

ANY = "*"  # any generated LCM type's ROS 2 mapping
EVERY = "**"  # any ROS 2 type at all


def found_in_graph(message_type: MessageType) -> bool:
    """Whether a source of this type learns each topic's type from the graph (`*` and `**`)."""
    return message_type.name in (ANY, EVERY)


def ros_message_type(lcm_type: LcmType) -> MessageType:
    """The ROS 2 message type an LCM type maps to, carrying its definition."""
    assert lcm_type.ros_type is not None, lcm_type.refused
    return MessageType(lcm_type.ros_type, CDR, Definition(lcm_type.ros2msg, lcm_type.rihs01))


def lcm_message_type(shared: Shared, ros_type: str) -> MessageType | None:
    """`ros_type` (`drake_lcm_msgs/msg/LcmtIiwaCommand`) as the CDR type of the known LCM type it
    maps, carrying its definition; None when no known LCM type maps to it."""
    lcm_type = shared.lcm_types.for_ros_type(ros_type)
    if lcm_type is None or lcm_type.ros_type is None:
        return None
    return ros_message_type(lcm_type)


class TopicTypes:
    """Picks the type a source subscribes a discovered topic with, saying once each topic and
    type a `*` source passes over."""

    def __init__(self, shared: Shared) -> None:
        self._shared = shared
        self._said: set[tuple[str, str]] = set()
        self._lock = threading.Lock()

    def pick(self, wanted: MessageType, topic: str, announced: Iterable[str]) -> MessageType | None:
        """The type to subscribe `topic` with, of those its publishers announce
        (`pkg/msg/Name`), for a source of type `wanted`; None to leave it alone."""
        announced = list(announced)
        if wanted.name == EVERY:
            return MessageType(announced[0], CDR) if announced else None
        if wanted.name != ANY:
            return wanted if wanted.name in announced else None
        for name in announced:
            found = lcm_message_type(self._shared, name)
            if found is not None:
                return found
        for name in announced:
            self.say(topic, name, "no generated LCM type")
        return None

    def say(self, topic: str, name: str, why: str) -> None:
        """Say once why `topic` of type `name` is not subscribed."""
        with self._lock:
            if (topic, name) in self._said:
                return
            self._said.add((topic, name))
        log.warning("viewer-bridge: %s is of type %s, %s: not subscribed (said once)", topic, name, why)
