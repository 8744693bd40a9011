"""The ROS 2 face of LCM types: message names, `.msg` texts, `ros2msg` schemas and RIHS01 hashes.

The mapping (docs/PROTOCOLS.md, "Any LCM type"): primitives by a fixed table; a one-dimensional
array of fixed size is `T[N]`, every other array `T[]` holding the elements in LCM's own
(row-major) order, with the length members kept as fields; a nested struct is a nested message
of its own package. A type that ROS 2 cannot express (one that contains itself, a name with no
valid ROS 2 form, two names that collide once converted) is refused with a reason that names it,
and so is every type that nests a refused one; the others are unaffected.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from viewer_bridge.errors import NameRefused
from viewer_bridge.lcmcodec.rosnames import constant_name, field_name, message_name, package_name
from viewer_bridge.lcmcodec.schema import Member, StructDef, recursive_groups

ROS_PRIMITIVES: Mapping[str, str] = {
    "int8_t": "int8",
    "int16_t": "int16",
    "int32_t": "int32",
    "int64_t": "int64",
    "byte": "uint8",
    "float": "float32",
    "double": "float64",
    "string": "string",
    "boolean": "bool",
}
SCHEMA_SEPARATOR = "=" * 80


@dataclass(frozen=True)
class RosMessage:
    """One LCM type's ROS 2 message: its names, `.msg` text and the LCM types it nests."""

    lcm_name: str
    package: str
    name: str
    definition: str  # the .msg text, with no comments of the .lcm file (see `message_text`)
    nested: tuple[str, ...]  # LCM full names of the struct types its members name, in order
    documented: str = ""  # the .msg text with the .lcm file's comments, for a workspace's msg/ files

    @property
    def ros_type(self) -> str:
        """`pkg/msg/Name`."""
        return f"{self.package}/msg/{self.name}"

    @property
    def short_type(self) -> str:
        """`pkg/Name`, as a `.msg` field and a `ros2msg` schema's `MSG:` line write it."""
        return f"{self.package}/{self.name}"


@dataclass
class RosMapping:
    """Every type's ROS 2 message, or the reason it has none."""

    messages: dict[str, RosMessage]  # by LCM full name
    refused: dict[str, str]  # LCM full name -> why
    _hashes: dict[str, str] = field(default_factory=dict)

    def ros2msg(self, lcm_name: str) -> str:
        """The MCAP `ros2msg` schema: the definition, then each nested type's after a separator."""
        main = self.messages[lcm_name]
        parts = [main.definition.rstrip("\n")]
        for nested in self.closure(lcm_name):
            message = self.messages[nested]
            parts.append(f"{SCHEMA_SEPARATOR}\nMSG: {message.short_type}\n{message.definition.rstrip()}")
        return "\n".join(parts) + "\n"

    def closure(self, lcm_name: str) -> list[str]:
        """Every type nested in `lcm_name`, at any depth, each once, in first-use order."""
        seen: dict[str, None] = {}
        pending = list(reversed(self.messages[lcm_name].nested))
        while pending:
            name = pending.pop()
            if name in seen or name == lcm_name:
                continue
            seen[name] = None
            pending.extend(reversed(self.messages[name].nested))
        return list(seen)

    def rihs01(self, lcm_name: str) -> str:
        """The RIHS01 type hash rmw_zenoh announces, computed by rosbags from the definitions."""
        if not self._hashes:
            store = self._typestore
            for name, message in self.messages.items():
                self._hashes[name] = store.hash_rihs01(message.ros_type)
        return self._hashes[lcm_name]

    @cached_property
    def _typestore(self) -> Any:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        store = get_typestore(Stores.EMPTY)
        types: dict[str, Any] = {}
        for message in self.messages.values():
            types.update(get_types_from_msg(message.definition, message.ros_type))
        store.register(types)
        return store


def ros_type_of(member: Member, messages: Mapping[str, RosMessage]) -> str:
    """The `.msg` type of a member: `float64`, `int32[3]`, `pkg/Name[]` ..."""
    base = ROS_PRIMITIVES.get(member.type_name) or messages[member.type_name].short_type
    if not member.dims:
        return base
    if len(member.dims) == 1 and not member.dims[0].is_variable:
        return f"{base}[{member.dims[0].count}]"
    return f"{base}[]"


def map_to_ros(structs: Mapping[str, StructDef]) -> RosMapping:
    """The ROS 2 messages of `structs` (every nested type must be among them)."""
    refused: dict[str, str] = {}
    names: dict[str, tuple[str, str]] = {}
    for lcm_name, struct in structs.items():
        try:
            names[lcm_name] = (package_name(struct.package), message_name(struct.name))
        except NameRefused as error:
            refused[lcm_name] = str(error)
    _refuse_collisions(names, refused)
    group = recursive_groups(structs)
    for lcm_name in structs:
        if lcm_name not in refused and (cycle := _cycle(lcm_name, structs, group)):
            refused[lcm_name] = f"{lcm_name} contains itself ({' -> '.join(cycle)}); ROS 2 messages cannot"
    messages: dict[str, RosMessage] = {}
    for lcm_name in _dependency_order(structs):
        struct = structs[lcm_name]
        if lcm_name in refused:
            continue
        blocked = next((name for name in _nested(struct) if name not in messages), None)
        if blocked is not None:
            refused[lcm_name] = f"it nests {blocked}, which has no ROS 2 form: {refused.get(blocked, '')}"
            continue
        try:
            definition = message_text(struct, messages)
        except NameRefused as error:
            refused[lcm_name] = f"{lcm_name}: {error}"
            continue
        documented = message_text(struct, messages, comments=True)
        package, name = names[lcm_name]
        messages[lcm_name] = RosMessage(
            lcm_name, package, name, definition, tuple(_nested(struct)), documented
        )
    return RosMapping(messages, refused)


def message_text(struct: StructDef, messages: Mapping[str, RosMessage], *, comments: bool = False) -> str:
    """The `.msg` text of one struct: a header naming the LCM type, constants with values, then fields.

    With `comments`, the `.lcm` file's comments come along as ROS 2 `.msg` comments, where rosidl
    puts them: the struct's in the file's leading block, each constant's and field's on the lines
    before it and, for one that followed it on its line, after it on its line (further lines
    indented, which rosidl adds to the same field). Without, the text is the same whatever the
    comments (and an lcm-gen'd class, which has none, gives the same text as its `.lcm` file): it is
    what the bridge announces (`ros2msg` schemas) and builds. Comments never change the RIHS01
    hash, which covers names and types only.
    """
    lines = [f"# {line}" for line in struct.comment.splitlines()] if comments else []
    lines.append(f"# LCM type {struct.full_name}")
    if comments:
        lines.append("")  # ends the file's comment block: the next comment is a field's
    used: dict[str, str] = {}  # constants and fields are checked apart: ROS 2 tells them by case
    for constant in struct.constants:
        name = constant_name(constant.name)
        _claim(used, name, constant.name)
        if isinstance(constant.value, float) and not math.isfinite(constant.value):
            raise NameRefused(f"constant {constant.name!r} is {constant.value}, which ROS 2 cannot write")
        value = (
            repr(float(constant.value)) if constant.type_name in ("float", "double") else str(constant.value)
        )
        line = f"{ROS_PRIMITIVES[constant.type_name]} {name}={value}"
        lines.extend(_commented(line, "", constant.comment, constant.trailing) if comments else [line])
    used = {}
    for member in struct.members:
        name = field_name(member.name)
        _claim(used, name, member.name)
        dims = "".join(f"[{dim.size}]" for dim in member.dims)
        note = f"LCM {member.type_name} {member.name}{dims}" if len(member.dims) > 1 else ""
        line = f"{ros_type_of(member, messages)} {name}"
        if comments:
            lines.extend(_commented(line, note, member.comment, member.trailing))
        else:
            lines.append(f"{line}  # {note}" if note else line)
    return "\n".join(lines).rstrip("\n") + "\n"  # no blank line closing a struct with no fields


def _commented(line: str, note: str, before: str, after: str) -> list[str]:
    """A constant or field line with its comments: `before` on lines of their own above it, the
    `note` and `after` behind it on its line, `after`'s further lines indented below it."""
    behind = [text for text in (note, *after.splitlines()) if text]
    return [
        *(f"# {text}" for text in before.splitlines()),
        f"{line}  # {behind[0]}" if behind else line,
        *(f"  # {text}" for text in behind[1:]),
    ]


def _claim(used: dict[str, str], ros_name: str, lcm_name: str) -> None:
    if ros_name in used:
        raise NameRefused(f"{used[ros_name]!r} and {lcm_name!r} both become {ros_name!r}")
    used[ros_name] = lcm_name


def _refuse_collisions(names: dict[str, tuple[str, str]], refused: dict[str, str]) -> None:
    first: dict[tuple[str, str], str] = {}
    for lcm_name, ros in sorted(names.items()):
        if ros in first:
            other = first[ros]
            reason = f"{other} and {lcm_name} both become {ros[0]}/msg/{ros[1]}"
            refused[other] = refused[lcm_name] = reason
        else:
            first[ros] = lcm_name


def _nested(struct: StructDef) -> Iterator[str]:
    seen: set[str] = set()
    for member in struct.members:
        if not member.is_primitive and member.type_name not in seen:
            seen.add(member.type_name)
            yield member.type_name


def _cycle(start: str, structs: Mapping[str, StructDef], group: Mapping[str, int]) -> list[str]:
    """A path of struct names from `start` back to itself, or [] when there is none: searched
    within `start`'s recursive group only (`schema.recursive_groups`), so that finding every
    type's costs the types' size once, not once per type."""
    stack: list[tuple[str, list[str]]] = [(start, [start])]
    seen: set[str] = set()
    while stack:
        name, path = stack.pop()
        for child in _nested(structs[name]):
            if child == start:
                return [*path, child]
            if child not in seen and group[child] == group[start]:
                seen.add(child)
                stack.append((child, [*path, child]))
    return []


def _dependency_order(structs: Mapping[str, StructDef]) -> list[str]:
    """Names with every nested type before the type that nests it (cycles broken arbitrarily)."""
    order: dict[str, None] = {}
    visiting: set[str] = set()
    for root in structs:
        stack: list[tuple[str, Iterator[str]]] = [(root, _nested(structs[root]))]
        if root in order:
            continue
        visiting.add(root)
        while stack:
            name, children = stack[-1]
            child = next(children, None)
            if child is None:
                stack.pop()
                visiting.discard(name)
                order[name] = None
            elif child not in order and child not in visiting:
                visiting.add(child)
                stack.append((child, _nested(structs[child])))
    return list(order)
