"""The `.msg` texts of ROS 2 Jazzy's interface packages that PyPI has no wheel for (INTERFACES:
tf2_msgs), from `rosbags`' type definitions and checked against rosbags' RIHS01 type hash."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from viewer_bridge.errors import RosInterfaceError

if TYPE_CHECKING:
    from rosbags.interfaces.typing import FieldDesc, Typesdict


@dataclass(frozen=True)
class Interface:
    """One ROS 2 interface package: its message names and the interface packages they use."""

    messages: tuple[str, ...]
    depends: tuple[str, ...]

    def files(self) -> tuple[str, ...]:
        return tuple(f"msg/{message}.msg" for message in self.messages)


INTERFACES: dict[str, Interface] = {
    "tf2_msgs": Interface(messages=("TFMessage", "TF2Error"), depends=("geometry_msgs",)),
}

_SEPARATOR = "=" * 80 + "\n"  # between the definitions in rosbags' generated msgdef


def message_text(typename: str) -> str:
    """The `.msg` text of a Jazzy message type (e.g. `tf2_msgs/msg/TFMessage`), from rosbags.

    The text is parsed back and must give the same RIHS01 type hash as rosbags' own definition:
    that hash is what rosidl computes from the file, and what peers match types by.
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    if typename not in store.fielddefs:
        raise RosInterfaceError(f"rosbags has no ROS 2 Jazzy type {typename}")
    text = store.generate_msgdef(typename, ros_version=2)[0].split(_SEPARATOR)[0]
    check = get_typestore(Stores.EMPTY)
    check.register({name: store.fielddefs[name] for name in _nested_types(store.fielddefs, typename)})
    check.register(get_types_from_msg(text, typename))
    if check.hash_rihs01(typename) != store.hash_rihs01(typename):
        raise RosInterfaceError(f"the .msg text generated for {typename} does not hash as rosbags' type")
    return text


def named_type(desc: FieldDesc) -> str | None:
    """The message type a field's description names (an array's or sequence's element type), or
    None for a base type."""
    node, arg = desc[1][0] if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE) else desc
    return arg if node == Nodetype.NAME and isinstance(arg, str) else None


def _nested_types(fielddefs: Typesdict, typename: str) -> set[str]:
    """Every message type that `typename` uses, directly or not (itself left out)."""
    found: set[str] = set()
    pending = [typename]
    while pending:
        for _, desc in fielddefs[pending.pop()][1]:
            name = named_type(desc)
            if name is not None and name not in found:
                found.add(name)
                pending.append(name)
    return found
