"""ROS 2 message types -> LCM types: the mapping of docs/PROTOCOLS.md, "ROS 2 types onto LCM".

ROS 2 definitions come from rosbags' type system (its Jazzy store holds every standard type;
`.msg` files and folders are parsed by rosbags too), as its `fielddefs`: per type, constants
`(name, type, value)` and fields `(name, (node type, description))`. Each mappable type becomes an
`.lcm` text, which is parsed back by `schema.parse_lcm`: the `StructDef` (and so the
fingerprint) is that of the file lcm-gen reads, by construction. `ros_cdr` compiles the
CDR -> LCM transcoders from `RosStruct`s, the wire-level view kept beside each struct.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from viewer_bridge.errors import SchemaError
from viewer_bridge.lcmcodec.schema import (
    MAX_NESTING,
    StructDef,
    constant_problem,
    fingerprint,
    name_problem,
    parse_lcm,
)
from viewer_bridge.util.partial import write_whole

Definitions = Mapping[str, tuple[list[Any], list[Any]]]  # rosbags' fielddefs

# ROS 2 primitive -> LCM member type. Unsigned integers LCM lacks widen to the next signed type;
# uint64 has none, so it is int64_t and a value from 2^63 up is refused on the way in.
LCM_TYPE_OF: Mapping[str, str] = {
    "bool": "boolean", "byte": "byte", "char": "byte", "uint8": "byte", "int8": "int8_t",
    "int16": "int16_t", "uint16": "int32_t", "int32": "int32_t", "uint32": "int64_t",
    "int64": "int64_t", "uint64": "int64_t", "float32": "float", "float64": "double",
    "string": "string", "wstring": "string",
}  # fmt: skip
# The type of a constant, where it differs from a member's: lcm-gen takes integer, float and double
# constants only, so a byte one widens to int16_t and a bool one is an int8_t 0 or 1. Strings have
# no LCM constant: they are written as a comment.
_CONSTANT_TYPE_OF: Mapping[str, str] = {**LCM_TYPE_OF, "bool": "int8_t", "byte": "int16_t", "char": "int16_t",
                                       "uint8": "int16_t"}  # fmt: skip
LENGTH_SUFFIX = "_length"  # a sequence `x` gets the member `int32_t x_length` just before it
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4  # rosbags' Nodetype values
_INT64_MAX = (1 << 63) - 1


@dataclass(frozen=True, slots=True)
class RosField:
    """One ROS 2 field as CDR holds it: `base` is a primitive name, or "" with `nested` a ROS type."""

    name: str
    base: str
    nested: str = ""
    kind: str = "scalar"  # "scalar", "array" (fixed `count` elements) or "sequence" (at most `count`, 0: any)
    count: int = 0
    # An LCM type's sequence (`cdr_to_lcm.lcm_wire`): the LCM dimensions its count must equal, each
    # a length field's name or a literal size. A mapped ROS 2 type's has none: its count is written.
    lengths: tuple[str, ...] = ()

    @property
    def length_field(self) -> str:
        return self.name + LENGTH_SUFFIX


@dataclass(frozen=True, slots=True)
class RosStruct:
    """A mappable ROS 2 type: its name, its LCM struct's full name, and its fields in CDR order."""

    ros_name: str
    lcm_name: str
    fields: tuple[RosField, ...]


@dataclass
class LcmFromRos:
    """The result of mapping a set of ROS 2 types: what maps (with every type it nests) and what not."""

    structs: dict[str, RosStruct] = field(default_factory=dict)  # by ROS 2 name
    lcm: dict[str, StructDef] = field(default_factory=dict)  # by LCM full name
    texts: dict[str, str] = field(default_factory=dict)  # the .lcm file of each, by LCM full name
    refused: dict[str, str] = field(default_factory=dict)  # ROS 2 name -> why

    def packed_fingerprint(self, ros_name: str) -> bytes:
        definition = self.lcm[self.structs[ros_name].lcm_name]
        return fingerprint(definition, self.lcm).to_bytes(8, "big")

    def write(self, folder: Path, wrote: Callable[[Path], None] | None = None) -> list[Path]:
        """One `.lcm` file per struct, as `folder/<package>/<Name>.lcm`; returns the paths
        (`wrote` hears each as it is written)."""
        written = []
        for full_name, text in sorted(self.texts.items()):
            package, name = full_name.split(".")
            path = folder / package / f"{name}.lcm"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_whole(path, text)  # a file under its name is always whole
            written.append(path)
            if wrote is not None:
                wrote(path)
        return written


def lcm_channel(topic: str) -> str:
    """The LCM channel a ROS 2 topic is carried on: the topic without its leading `/`
    (`/joint_states` -> `joint_states`, `/arm/state` -> `arm/state`; LCM channels may hold `/`)."""
    return topic.removeprefix("/")


def lcm_full_name(ros_name: str) -> str:
    """`pkg/msg/Name` (or `pkg/Name`) -> `pkg.Name`."""
    parts = ros_name.split("/")
    return f"{parts[0]}.{parts[-1]}"


def load_ros_definitions(sources: Sequence[str]) -> tuple[dict[str, tuple[list[Any], list[Any]]], list[str]]:
    """The Jazzy store's definitions plus those of the `.msg` files and folders among `sources`, and
    the ROS 2 type names `sources` ask for: a type (`pkg/msg/Name` or `pkg/Name`), a package (all of
    its types), or a path (the types of its `.msg` files, named `pkg/msg/Name` from their place
    `.../pkg/msg/Name.msg`, or `.../pkg/Name.msg`)."""
    from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    wanted: list[str] = []
    custom: dict[str, Any] = {}
    for source in sources:
        path = Path(source)
        if path.exists():
            files = sorted(path.rglob("*.msg")) if path.is_dir() else [path]
            if not files:
                raise SchemaError(source, 0, "no .msg files here")
            for file in files:
                name = _msg_name(file)
                try:
                    custom.update(get_types_from_msg(file.read_text(), name))
                except TypesysError as error:  # one line naming the file, as for a bad .lcm file
                    raise SchemaError(str(file), 0, f"not a .msg definition rosbags reads: {error}") from None
                wanted.append(name)
        elif "/" in source:
            parts = source.strip("/").split("/")
            wanted.append(source if len(parts) == 3 else f"{parts[0]}/msg/{parts[-1]}")
        else:
            found = [name for name in store.fielddefs if name.split("/")[0] == source]
            if not found:
                raise SchemaError(
                    source, 0, "neither a file, a ROS 2 type nor a package of the Jazzy type store"
                )
            wanted.extend(sorted(found))
    definitions = {**store.fielddefs, **custom}
    return definitions, list(dict.fromkeys(wanted))


def _msg_name(file: Path) -> str:
    parent = file.parent
    package = parent.parent.name if parent.name == "msg" else parent.name
    return f"{package}/msg/{file.stem}"


def map_ros_types(definitions: Definitions, names: Iterable[str]) -> LcmFromRos:
    """Map `names` and every type they nest; a type that cannot be mapped is refused with its
    reason, and so is every type that nests it (the others go on)."""
    result = LcmFromRos()
    pending: dict[str, RosStruct] = {}
    order: list[str] = []
    for name in names:
        _visit(definitions, name, pending, result.refused, order)
    _refuse_shared_names(pending, result.refused)
    cause = dict(result.refused)  # a refused type's first reason, said once by all that nest it
    depth: dict[str, int] = {}  # struct levels, as `schema.nesting_depths` counts them
    for ros_name in order:
        struct = pending.get(ros_name)
        if struct is None or ros_name in result.refused:
            continue
        if any(f.nested in result.refused for f in struct.fields):
            bad = next(f for f in struct.fields if f.nested in result.refused)
            cause[ros_name] = cause[bad.nested]
            result.refused[ros_name] = f"field {bad.name}: {bad.nested} is refused ({cause[ros_name]})"
            continue
        depth[ros_name] = 1 + max((depth.get(f.nested, 0) for f in struct.fields if f.nested), default=0)
        if depth[ros_name] > MAX_NESTING:  # `order` has children first: the shallowest such type
            cause[ros_name] = result.refused[ros_name] = (
                f"it nests types {depth[ros_name]} levels deep, more than the {MAX_NESTING} a type may"
            )
            continue
        text = lcm_text(struct, definitions[ros_name][0], pending)
        try:  # what lcm-gen will read: parsed back, so that the fingerprint is of these very lines
            (definition,) = parse_lcm(text, f"<{ros_name}>")
        except SchemaError as error:  # a value no rule here foresaw: this type out, the others on
            result.refused[ros_name] = f"its .lcm text does not parse: {error}"
            continue
        result.structs[ros_name] = struct
        result.texts[struct.lcm_name] = text
        result.lcm[struct.lcm_name] = definition
    return result


def wire_structs(definitions: Definitions, name: str) -> dict[str, RosStruct]:
    """`name` and every type it nests as wire structs (children first), for writing CDR; raises
    `SchemaError` naming the first type that has no definition or cannot be read."""
    pending: dict[str, RosStruct] = {}
    refused: dict[str, str] = {}
    _visit(definitions, name, pending, refused, [])
    for refused_name, reason in refused.items():
        raise SchemaError(f"<{name}>", 0, f"{refused_name}: {reason}")
    return pending


def _visit(definitions: Definitions, root: str, pending: dict[str, RosStruct], refused: dict[str, str],
           order: list[str]) -> None:  # fmt: skip
    """Read `root` and what it nests, children first (so `order` has every type after its
    children): a walk with a stack of its own, so that no chain of types is too long for Python's."""
    reading: dict[str, RosStruct] = {}  # the types on the way down to the one read now
    path: list[tuple[str, Iterator[str]]] = []  # and their nested types not yet read

    def enter(name: str) -> None:
        if name in pending or name in refused or name in reading:
            return
        if name not in definitions:
            refused[name] = "no definition (not in the Jazzy store nor among the .msg files given)"
            return
        try:
            reading[name] = _ros_struct(name, definitions[name])
        except ValueError as error:
            refused[name] = str(error)
            return
        path.append((name, iter([f.nested for f in reading[name].fields if f.nested])))

    enter(root)
    while path:
        name, nested = path[-1]
        child = next(nested, None)
        if child is not None:
            enter(child)
            continue
        path.pop()
        pending[name] = reading.pop(name)
        order.append(name)


def _ros_struct(name: str, definition: tuple[list[Any], list[Any]]) -> RosStruct:
    """The wire view of one definition, or ValueError saying why it has no LCM struct."""
    lcm_name = lcm_full_name(name)
    problem = name_problem(lcm_name.split(".")[1], "type name", attribute=False)
    if problem:
        raise ValueError(problem)
    constants, fields = definition
    ros_fields = tuple(_ros_field(name, field_name, desc) for field_name, desc in fields)
    taken: dict[str, str] = {}
    for what, member in [*((f"field {f.name}", f.name) for f in ros_fields),
                         *((f"constant {c[0]}", c[0]) for c in constants)]:  # fmt: skip
        problem = name_problem(member, what, attribute=True)
        if problem:
            raise ValueError(problem)
        taken[member] = what
    for ros_field in ros_fields:
        if ros_field.kind == "sequence" and ros_field.length_field in taken:
            raise ValueError(f"field {ros_field.name}'s length field {ros_field.length_field} "
                             f"would collide with {taken[ros_field.length_field]}")  # fmt: skip
        taken[ros_field.length_field] = f"the length field of {ros_field.name}"
    return RosStruct(name, lcm_name, ros_fields)


def _ros_field(owner: str, name: str, desc: tuple[int, Any]) -> RosField:
    node, value = desc
    if node in (_ARRAY, _SEQUENCE):
        element, count = value
        inner = _ros_field(owner, name, element)
        if inner.kind != "scalar":
            raise ValueError(f"field {name}: arrays of arrays do not exist in ROS 2")
        kind = "array" if node == _ARRAY else "sequence"
        return RosField(name, inner.base, inner.nested, kind, count)
    if node == _NAME:
        # rosbags' .msg parser does not know `wstring` and reads it as a type of the same package.
        if value.rsplit("/", 1)[-1] == "wstring":
            return RosField(name, "wstring")
        return RosField(name, "", value)
    base = value[0]
    if base not in LCM_TYPE_OF:
        raise ValueError(f"field {name}: ROS 2 type {base} has no LCM counterpart")
    return RosField(name, base)


def _refuse_shared_names(pending: Mapping[str, RosStruct], refused: dict[str, str]) -> None:
    """Two ROS 2 types that would be one LCM struct (`a/msg/X`, `a/srv/X`) are both refused."""
    by_lcm: dict[str, list[str]] = {}
    for struct in pending.values():
        by_lcm.setdefault(struct.lcm_name, []).append(struct.ros_name)
    for lcm_name, ros_names in by_lcm.items():
        if len(ros_names) > 1:
            for ros_name in ros_names:
                refused[ros_name] = f"{' and '.join(ros_names)} would both be LCM struct {lcm_name}"


def lcm_text(
    struct: RosStruct, constants: Sequence[tuple[str, str, Any]], structs: Mapping[str, RosStruct]
) -> str:
    """The `.lcm` file of one struct, with comments saying what LCM does not carry."""
    package, name = struct.lcm_name.split(".")
    lines = [f"// ROS 2 type {struct.ros_name}, written by viewer-bridge lcm-types generate", f"package {package};", "",
             f"struct {name}", "{"]  # fmt: skip
    lines.extend(_constant_line(*constant) for constant in constants)
    for ros_field in struct.fields:
        lcm_type = structs[ros_field.nested].lcm_name if ros_field.nested else LCM_TYPE_OF[ros_field.base]
        note = _field_note(ros_field)
        if ros_field.kind == "sequence":
            lines.append(f"    int32_t {ros_field.length_field};")
            size = f"[{ros_field.length_field}]"
        else:
            size = f"[{ros_field.count}]" if ros_field.kind == "array" else ""
        lines.append(f"    {lcm_type} {ros_field.name}{size};{note}")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _field_note(ros_field: RosField) -> str:
    notes = []
    if ros_field.base in ("uint16", "uint32", "uint64", "wstring", "char"):
        notes.append(f"ROS 2 {ros_field.base}")
    if ros_field.base == "uint64":
        notes.append("values from 2^63 up are refused")
    if ros_field.kind == "sequence" and ros_field.count:
        notes.append(f"at most {ros_field.count} elements")
    return f"  // {', '.join(notes)}" if notes else ""


def _constant_line(name: str, ros_type: str, value: Any) -> str:
    lcm_type = _CONSTANT_TYPE_OF.get(ros_type)
    if lcm_type is None or lcm_type == "string" or (ros_type == "uint64" and value > _INT64_MAX):
        return f"    // {ros_type} {name} = {value!r} (no LCM constant can hold it)"
    if lcm_type in ("float", "double"):
        text = repr(float(value)).replace("e+", "e")  # lcm-gen's lexer takes 1e20, not 1e+20
        problem = constant_problem(lcm_type, float(value), text)
        if problem:
            return f"    // {ros_type} {name} = {text} (no LCM constant: {problem})"
    else:
        text = str(int(value))
    return f"    const {lcm_type} {name} = {text};"


def definitions_from_msgdef(ros_type: str, text: str) -> dict[str, tuple[list[Any], list[Any]]]:
    """The definitions in a `ros2msg` schema (as MCAP and rosbag2 store them): the type's `.msg`,
    then for each type it nests a line of `=` and `MSG: pkg/Name` before that type's `.msg`."""
    from rosbags.typesys import get_types_from_msg

    found: dict[str, tuple[list[Any], list[Any]]] = {}
    name = ros_type
    for section in _SEPARATOR.split(text):
        first, _, rest = section.strip("\n").partition("\n")
        body = section
        if first.startswith("MSG: "):
            parts = first[5:].strip().split("/")
            name, body = (f"{parts[0]}/msg/{parts[-1]}" if len(parts) == 2 else "/".join(parts)), rest
        found.update(get_types_from_msg(body, name))
    return found


_SEPARATOR = re.compile(r"^={3,}[ \t]*$", re.MULTILINE)
