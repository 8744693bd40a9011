"""How LCM names become ROS 2 names: packages, messages, fields, constants, and channels as topics.

The rules (docs/PROTOCOLS.md, "Any LCM type"):
- type `pkg.sub.struct_name` -> package `pkg_sub_lcm_msgs`, message `StructName` (each `_`-separated
  word capitalised); a type with no package -> `lcm_msgs`;
- a field to snake_case (an upper-case letter after a lower-case letter or a digit starts a new
  word: `jointAngles` -> `joint_angles`), a constant to UPPER_SNAKE_CASE (`maxJoints` -> `MAX_JOINTS`);
  package words are snake-cased the same way;
- then, because ROS 2 forbids them in names, runs of underscores become one and underscores at
  either end are dropped (`_private` -> `private`, `a__b` -> `a_b`);
- a name that still breaks ROS 2's rules (rosidl_adapter's patterns) is a `NameRefused` naming it.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from viewer_bridge.errors import NameRefused

if TYPE_CHECKING:
    from viewer_bridge.lcmcodec.schema import StructDef


# rosidl_adapter's patterns for valid names (the one set of them: ros_build checks packages by them too).
# each used with fullmatch: `$` takes "name\n"
PACKAGE_PATTERN = re.compile(r"(?!.*__)(?!.*_\Z)[a-z][a-z0-9_]*")
MESSAGE_PATTERN = re.compile(r"[A-Z][A-Za-z0-9]*")
_FIELD = PACKAGE_PATTERN
_CONSTANT = re.compile(r"[A-Z]([A-Z0-9_]?[A-Z0-9]+)*")

_WORD_START = re.compile(r"(?<=[a-z0-9])(?=[A-Z])")
_UNDERSCORES = re.compile(r"_+")
_NOT_TOPIC = re.compile(r"[^A-Za-z0-9_]")
PACKAGE_SUFFIX = "_lcm_msgs"
NO_PACKAGE = "lcm_msgs"


def _snake(name: str) -> str:
    return _tidy(_WORD_START.sub("_", name).lower())


def _tidy(name: str) -> str:
    return _UNDERSCORES.sub("_", name).strip("_")


def field_name(name: str) -> str:
    """The ROS 2 field name of LCM member `name`."""
    result = _snake(name)
    if not _FIELD.fullmatch(result):
        raise NameRefused(f"field {name!r} has no valid ROS 2 name (got {result!r})")
    return result


def field_names(struct: StructDef) -> dict[str, str]:
    """Each member's name in a message's dict or JSON (`LcmType.to_dict`, `from_dict`): its ROS 2
    field name. A struct with no ROS 2 form for them all (a name with none, two names with one)
    keeps its LCM names, so that `viewer-bridge dump` still shows every field."""
    try:
        names = {member.name: field_name(member.name) for member in struct.members}
    except NameRefused:
        return {member.name: member.name for member in struct.members}
    if len(set(names.values())) != len(names):
        return {member.name: member.name for member in struct.members}
    return names


def field_path(path: str) -> str:
    """A field path of LCM names (`where.frameId[2]`, as the LCM decoder's errors say it) in ROS 2
    names (`where.frame_id[2]`); a part with no ROS 2 name (`<fingerprint>`) stays as it is."""
    return ".".join(_path_part(part) for part in path.split("."))


def _path_part(part: str) -> str:
    name, bracket, indices = part.partition("[")
    try:
        return field_name(name) + bracket + indices
    except NameRefused:
        return part


def constant_name(name: str) -> str:
    """The ROS 2 constant name of LCM constant `name`."""
    result = _snake(name).upper()
    if not _CONSTANT.fullmatch(result):
        raise NameRefused(f"constant {name!r} has no valid ROS 2 name (got {result!r})")
    return result


def package_name(lcm_package: str) -> str:
    """The ROS 2 package of LCM package `lcm_package` (`""` for a type with none)."""
    if not lcm_package:
        return NO_PACKAGE
    result = "_".join(_snake(word) for word in lcm_package.split(".")) + PACKAGE_SUFFIX
    result = _tidy(result)
    if not PACKAGE_PATTERN.fullmatch(result):
        raise NameRefused(f"package {lcm_package!r} has no valid ROS 2 name (got {result!r})")
    return result


def message_name(struct_name: str) -> str:
    """The ROS 2 message name of LCM struct `struct_name` (`lcmt_iiwa_status` -> `LcmtIiwaStatus`)."""
    result = "".join(word[:1].upper() + word[1:] for word in struct_name.split("_"))
    if not MESSAGE_PATTERN.fullmatch(result):
        raise NameRefused(f"type {struct_name!r} has no valid ROS 2 message name (got {result!r})")
    return result


def ros_topic_for_channel(channel: str) -> str:
    """The ROS 2 topic of an LCM channel: `/lcm/` + the channel, other characters than [A-Za-z0-9_] as `_`."""
    return "/lcm/" + _NOT_TOPIC.sub("_", channel)
