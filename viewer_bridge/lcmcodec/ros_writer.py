"""Python values -> ROS 2 CDR bytes, with code generated per type and compiled once.

The bridge's own ROS 2 messages (TF, markers, images, clouds, camera info, shapes, wrenches) are
written here from the scene's numbers, where `cdr.py` writes CDR from LCM bytes. Both emit CDR
with the same pieces (`codegen`: one packer per position modulo 8 for a run of scalars, the glue
of padding and count before an array), so CDR has one generated way of being written; rosbags
writes only the message objects a user hands the library.

A message is given as a tuple of its fields in the order of its definition (a NamedTuple will
do), a nested message as a tuple too: `sensor_msgs/msg/Image` is
`(((sec, nanosec), frame_id), height, width, encoding, is_bigendian, step, data)`. Nested
messages are written inline, so a run of scalars spanning several of them (a Marker's id, type,
action, pose, scale, colour and lifetime) is one `struct` pack. Strings are `str`. Primitive
arrays and sequences are any sequence of numbers or a numpy array (bytes for uint8, byte, char
and int8); a sequence of messages is a list of tuples, or, for messages of one primitive type
only (`geometry_msgs/Point`, `std_msgs/ColorRGBA`, `shape_msgs/MeshTriangle`), an N x k numpy
array written in one copy. Any empty value with a length (`()`, `[]`, an empty array) is an empty
sequence. Short strings are encoded once and kept (a few thousand, then the cache starts over):
a scene writes the same frame ids, namespaces and empty strings over and over. Three or more
strings and sequences in a row (a marker's texture, text and mesh fields) are kept the same way,
as one piece, when their values are strings, empty bytes and empty tuples.

`marks` name fields (dotted paths from the root, through sequences too: `transforms.transform`)
whose payload offsets `write_marked` reports, one per time the field is written: a message
written once as a template can then take new numbers at those offsets, frame after frame.

A value that is not what its field holds raises `EncodeError` naming the type, the field path and
why: a wrong number of fields, an integer out of its type's range or a float given for it, a
fixed array of the wrong length, a bounded sequence too long, a string with a NUL in it or that
is no valid Unicode.
"""

from __future__ import annotations

import itertools
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from viewer_bridge.errors import EncodeError, SchemaError
from viewer_bridge.lcmcodec.codegen import (
    CDR_LE,
    COUNT_AFTER_PAD,
    SourceWriter,
    aligned_starts,
    call_child,
    cdr_glue,
    cdr_packers,
)
from viewer_bridge.lcmcodec.from_ros import RosField, RosStruct, wire_structs

# ROS 2 primitive -> (little-endian struct code, size, numpy type)
_PRIMITIVES: Mapping[str, tuple[str, int, str]] = {
    "bool": ("?", 1, "?"), "byte": ("B", 1, "u1"), "char": ("B", 1, "u1"), "uint8": ("B", 1, "u1"),
    "int8": ("b", 1, "i1"), "int16": ("h", 2, "<i2"), "uint16": ("H", 2, "<u2"), "int32": ("i", 4, "<i4"),
    "uint32": ("I", 4, "<u4"), "int64": ("q", 8, "<i8"), "uint64": ("Q", 8, "<u8"), "float32": ("f", 4, "<f4"),
    "float64": ("d", 8, "<f8"),
}  # fmt: skip
_BYTE_BASES = frozenset(("uint8", "byte", "char", "int8"))  # their arrays and sequences may be bytes
_RUN_ARRAY_MAX = 16  # a fixed array this short is packed inside its run of scalars
_PACK_ERRORS = (struct.error, TypeError, OverflowError, ValueError)


class RosWriter:
    """The compiled CDR writer of one ROS 2 type (`ros_writer` makes and keeps them)."""

    def __init__(
        self, type_name: str, marks: tuple[str, ...], body: Any, shape: Any, default: tuple[Any, ...]
    ) -> None:
        self.type_name = type_name
        self.marks = marks
        self.default = default  # the message with every field at ROS's default (0, "", empty)
        self._body = body
        self._shape = shape  # the field names, nested as the value is: for naming a bad value
        self._names = frozenset(name for name, _ in shape)
        self._compose = _composer([name for name, _ in shape], default)

    def write_fields(self, fields: Mapping[str, Any]) -> bytes:
        """The CDR of the message whose top-level fields are `fields` by name, the others at
        their defaults (for messages made field by field, e.g. from a table's values)."""
        if not self._names.issuperset(fields):
            unknown = sorted(set(fields) - self._names)[0]
            raise EncodeError(self.type_name, unknown, "no such field")
        return self.write(self._compose(fields))

    def write(self, value: Any) -> bytes:
        """The CDR of `value`, with its encapsulation header. Raises `EncodeError` (see the module)."""
        out: list[Any] = [CDR_LE]
        self._call(value, out, None)
        return b"".join(out)

    def write_marked(self, value: Any) -> tuple[bytes, dict[str, list[int]]]:
        """The CDR of `value`, and the payload offset (after the 4-byte header, where CDR's
        alignment counts from) of each marked field, in the order they were written."""
        out: list[Any] = [CDR_LE]
        marks: dict[str, list[int]] = {path: [] for path in self.marks}
        self._call(value, out, marks)
        return b"".join(out), marks

    def _call(self, value: Any, out: list[Any], marks: dict[str, list[int]] | None) -> None:
        try:
            self._body(value, out, 0, marks)
        except _Unpacking:
            raise _shape_error(self.type_name, self._shape, value, "") from None


@lru_cache(maxsize=256)
def ros_writer(type_name: str, marks: tuple[str, ...] = ()) -> RosWriter:
    """The writer of `type_name` (`pkg/msg/Name`, a ROS 2 Jazzy type), compiled on first ask.

    Raises `SchemaError` for a type with no definition, `EncodeError` for a mark naming no field.
    """
    from rosbags.typesys import Stores, get_typestore  # the definitions: loaded when first needed

    structs = wire_structs(get_typestore(Stores.ROS2_JAZZY).fielddefs, type_name)
    return compile_writer(structs, type_name, marks)


def compile_writer(
    structs: Mapping[str, RosStruct], type_name: str, marks: tuple[str, ...] = ()
) -> RosWriter:
    """The writer of `type_name` from its wire structs and those it nests (`from_ros.wire_structs`)."""
    generator = _Generator(structs, marks)
    root = generator.function(type_name, "")
    unused = set(marks) - generator.marked
    if unused:
        raise EncodeError(type_name, sorted(unused)[0], "no such field to mark")
    namespace: dict[str, Any] = {**_HELPERS, **generator.names}
    exec(compile(generator.out.source(), f"<cdr writer {type_name}>", "exec"), namespace)  # noqa: S102
    shape = generator.shape(type_name)
    return RosWriter(type_name, marks, namespace[root], shape, _default(structs, type_name))


# --- the pieces of a struct, flattened: nested structs written inline ----------------------------


@dataclass(frozen=True, slots=True)
class _Leaf:
    """One thing written on its own or in a run: `kind` is "scalar" (a primitive, or a short fixed
    array of them, in a run), "string", "numbers" (a primitive array or sequence), "strings" or
    "structs" (an array or sequence of them); `var` holds its value in the generated code."""

    kind: str
    var: str
    path: str  # from the function's type, for errors
    full: str  # from the message's root, for marks
    field: RosField
    marks: tuple[str, ...] = ()  # marked paths that start at this leaf


class _Generator:
    """Writes one function per struct type reached as the element of an array or sequence (and
    the root), each with every nested struct inline."""

    def __init__(self, structs: Mapping[str, RosStruct], marks: tuple[str, ...]) -> None:
        self.structs = structs
        self.marks = set(marks)
        self.marked: set[str] = set()
        self.out = SourceWriter()
        self.names: dict[str, object] = {}  # packers and constants the generated code reads
        self.idents: dict[tuple[str, str], str] = {}
        self._count = 0

    def function(self, type_name: str, root: str) -> str:
        """The name of the function writing `type_name`, found at path `root` from the message's
        root (for marks; its errors name fields from `type_name`)."""
        key = (type_name, root)
        if key in self.idents:
            return self.idents[key]
        ident = self.idents[key] = f"W{len(self.idents)}"
        leaves: list[_Leaf] = []
        pattern = self._flatten(type_name, "", root, leaves)
        body = SourceWriter()
        body.depth = 1
        self._body(type_name, leaves, body)
        out = self.out
        out.line(f"def {ident}(v, out, pos, marks):")
        with out.indent():
            out.line(f"{pattern} = v")
        out.lines += body.lines
        with out.indent():
            out.line("return pos")
        return ident

    def shape(self, type_name: str) -> Any:
        """The field names of `type_name` nested as its value is: (name, nested or None) pairs."""
        return tuple(
            (f.name, self.shape(f.nested) if f.nested and f.kind == "scalar" else None)
            for f in self.structs[type_name].fields
        )

    def _var(self) -> str:
        self._count += 1
        return f"a{self._count}"

    def _flatten(self, type_name: str, prefix: str, root: str, leaves: list[_Leaf]) -> str:
        """Append the leaves of `type_name` (at path `prefix` in the function's type, which is at
        `root` in the message) and return the tuple pattern that unpacks its value into their
        variables."""
        fields = self.structs[type_name].fields
        if not fields:  # ROS 2 gives an empty message one uint8, whatever the value holds
            leaves.append(
                _Leaf("scalar", "0", prefix, root, RosField("structure_needs_at_least_one_member", "uint8"))
            )
            return "_"
        targets = []
        for field in fields:
            path = f"{prefix}.{field.name}" if prefix else field.name
            full = f"{root}.{path}" if root else path
            first = len(leaves)
            if field.nested and field.kind == "scalar":
                targets.append(self._flatten(field.nested, path, root, leaves))
            else:
                var = self._var()
                targets.append(var)
                leaves.append(_Leaf(_kind(field), var, path, full, field))
            if full in self.marks and len(leaves) > first:
                self.marked.add(full)
                leaves[first] = _with_mark(leaves[first], full)
        return f"({', '.join(targets)},)"

    # --- writing a struct's leaves ----------------------------------------------------------------

    def _body(self, type_name: str, leaves: list[_Leaf], out: SourceWriter) -> None:
        """The leaves in order (`_sort`): scalars in runs, one pack each; strings and sequences
        as a kept stretch where `_STRETCH_MIN` of them or more come in a row, else one by one."""
        for sort, group in itertools.groupby(leaves, _sort):
            if sort == "run":
                self._run(type_name, list(group), out)
                continue
            group_leaves = list(group)
            if sort == "stretch" and len(group_leaves) >= _STRETCH_MIN:
                self._stretch(type_name, group_leaves, out)
            else:
                for leaf in group_leaves:
                    self._leaf(type_name, leaf, out)

    def _stretch(self, type_name: str, group: list[_Leaf], out: SourceWriter) -> None:
        """Strings and sequences in a row (a marker's texture, text and mesh fields): their bytes
        from `_STRETCHES` when the same values were written before at the same position modulo 4,
        else written one by one and kept (`_keep`)."""
        # The stretch's own number first: the same values may be written otherwise elsewhere
        # ("" is an empty string in one place, an empty sequence in another).
        values = ", ".join(_key_value(leaf) for leaf in group)
        out.line(f"key = ({next(_STRETCH_NUMBERS)}, {values}, pos & 3)")
        out.line("try:")
        with out.indent():
            out.line("s = _STRETCHES[key]")
        out.line("except _NOT_KEPT:")  # new values, or a list or array among them: unhashable
        with out.indent():
            out.line("first = len(out)")
            for leaf in group:
                self._leaf(type_name, leaf, out)
            out.line("_keep(key, out, first)")
        out.line("else:")
        with out.indent():
            out.line("out.append(s)")
            out.line("pos += len(s)")

    def _leaf(self, type_name: str, leaf: _Leaf, out: SourceWriter) -> None:
        """One string, array or sequence."""
        self._mark(leaf, out, self._start(leaf))
        if leaf.field.kind == "sequence":
            self._unless_empty(leaf, out)
        if leaf.kind == "string":
            self._string(type_name, leaf, out)
        elif leaf.kind == "numbers":
            self._numbers(type_name, leaf, out)
        elif leaf.kind == "strings":
            field = leaf.field
            out.line(f"pos = _strings({leaf.var}, out, pos, {type_name!r}, {leaf.path!r}, "
                     f"{field.kind == 'array'}, {field.count})")  # fmt: skip
        else:
            self._structs(type_name, leaf, out)
        if leaf.field.kind == "sequence":
            out.depth -= 1

    def _unless_empty(self, leaf: _Leaf, out: SourceWriter) -> None:
        """An empty sequence, the usual value of many (a marker's points, colours, texture and mesh
        data), as its count from a table; the code after this, for the others, is indented."""
        out.line("try:")
        with out.indent():
            out.line(f"n = len({leaf.var})")
        out.line("except TypeError:")  # no sequence: the code for the others says so
        with out.indent():
            out.line("n = -1")
        out.line("if n == 0:")
        with out.indent():
            out.line("s = _NO_ITEMS[pos & 3]")
            out.line("out.append(s)")
            out.line("pos += len(s)")
        out.line("else:")
        out.depth += 1

    def _string(self, type_name: str, leaf: _Leaf, out: SourceWriter) -> None:
        """A string, inline (a viewer's marker has eight): its bytes, padding first, from `_TEXTS`
        (`_text` encodes, checks and keeps those not there)."""
        out.line("try:")
        with out.indent():
            out.line(f"s = _TEXTS[{leaf.var}][pos & 3]")
        out.line("except _NOT_KEPT:")
        with out.indent():
            out.line(f"s = _text({leaf.var}, pos, {type_name!r}, {leaf.path!r})")
        out.line("out.append(s)")
        out.line("pos += len(s)")

    def _start(self, leaf: _Leaf) -> str:
        """Where a leaf written on its own starts: a string's or sequence's count, 4-aligned, or a
        fixed array's first primitive."""
        if leaf.field.kind == "array" and leaf.kind == "numbers":
            return f"pos + (-pos & {_PRIMITIVES[leaf.field.base][1] - 1})"
        return "pos + (-pos & 3)"

    def _mark(self, leaf: _Leaf, out: SourceWriter, position: str) -> None:
        for path in leaf.marks:
            out.line(f"if marks is not None: marks[{path!r}].append({position})")

    def _run(self, type_name: str, run: list[_Leaf], out: SourceWriter) -> None:
        """Scalars (and short fixed arrays) in a row: one pack, its padding chosen by `pos % 8`."""
        codes: list[tuple[str, int]] = []
        args: list[str] = []
        firsts: list[int] = []  # each leaf's first scalar, for its marks
        for leaf in run:
            code, size, _ = _PRIMITIVES[leaf.field.base]
            firsts.append(len(codes))
            count = leaf.field.count if leaf.field.kind == "array" else 1
            codes += [(code, size)] * count
            args.append(f"*{leaf.var}" if leaf.field.kind == "array" else leaf.var)
        name = f"R{len(self.names)}"
        packers, sizes = cdr_packers(codes)
        unpadded = all(size == 1 for _, size in codes)  # bytes only (a bool): the same at every position
        if unpadded:
            self.names[name] = packers[0]
            packer, step = name, str(sizes[0])
        else:
            self.names[name], self.names[name + "_N"] = packers, sizes
            out.line("k = pos & 7")
            packer, step = f"{name}[k]", f"{name}_N[k]"
        out.line("try:")
        with out.indent():
            out.line(f"out.append({packer}.pack({', '.join(args)}))")
        out.line("except _PACK_ERRORS:")
        with out.indent():
            paths = tuple((leaf.path, leaf.field.base, leaf.field.count if leaf.field.kind == "array" else 0)
                          for leaf in run)  # fmt: skip
            out.line(f"raise _run_error({type_name!r}, {paths!r}, ({', '.join(leaf.var for leaf in run)},)) "
                     "from None")  # fmt: skip
        for leaf, first in zip(run, firsts, strict=True):
            if leaf.marks and unpadded:
                self._mark(leaf, out, f"pos + {first}")
            elif leaf.marks:
                starts = [aligned_starts(phase, [size for _, size in codes])[first] for phase in range(8)]
                self.names[f"{name}_AT{first}"] = starts
                self._mark(leaf, out, f"pos + {name}_AT{first}[k]")
        out.line(f"pos += {step}")

    def _numbers(self, type_name: str, leaf: _Leaf, out: SourceWriter) -> None:
        field = leaf.field
        fixed = field.kind == "array"
        if not fixed and not field.count and field.base in _BYTE_BASES:
            out.line(f"if type({leaf.var}) is bytes:")  # the bytes of an image, a cloud, a mesh file
            with out.indent():
                out.line("p = -pos & 3")
                out.line(f"out += (_COUNT_AFTER_PAD[p].pack(len({leaf.var})), {leaf.var})")
                out.line(f"pos += p + 4 + len({leaf.var})")
            out.line("else:")
            out.depth += 1
        numbers = (f"pos = _numbers({leaf.var}, {self._dtype(field.base)}, out, pos, {type_name!r}, {leaf.path!r}, "
                   f"{fixed}, {field.count}, 1)")  # fmt: skip
        if not fixed and field.base != "bool":  # `n` is its length (`_unless_empty`)
            self._short_list(leaf, numbers, out)
        else:
            out.line(numbers)
        if not fixed and not field.count and field.base in _BYTE_BASES:
            out.depth -= 1

    def _short_list(self, leaf: _Leaf, numbers: str, out: SourceWriter) -> None:
        """A short list of numbers (a shape's dimensions, a camera's distortion) in one `struct`
        pack; anything else, or a value that does not pack, through `numbers` (`_numbers`)."""
        code, size, _ = _PRIMITIVES[leaf.field.base]
        name = f"P_{leaf.field.base}"
        self.names[name] = [struct.Struct(f"<{count}{code}") for count in range(_SHORT + 1)]
        # Each count's glue (padding, count, padding) by position modulo 8, looked up, not computed.
        self.names[f"G_{size}"] = [[cdr_glue(phase, count, size, True) for count in range(_SHORT + 1)]
                                   for phase in range(8)]  # fmt: skip
        limit = min(_SHORT, leaf.field.count or _SHORT)  # a bounded sequence: longer ones are refused there
        out.line(f"if type({leaf.var}) is list and n <= {limit}:")
        with out.indent():
            out.line("try:")
            with out.indent():
                out.line(f"s = {name}[n].pack(*{leaf.var})")
            out.line("except _PACK_ERRORS:")
            with out.indent():
                out.line(numbers)  # names what is wrong
            out.line("else:")
            with out.indent():
                out.line(f"g, step = G_{size}[pos & 7][n]")
                out.line("out += (g, s)")
                out.line("pos += step")
        out.line("else:")
        with out.indent():
            out.line(numbers)

    def _dtype(self, base: str) -> str:
        """The name under which the generated code finds the numpy type of primitive `base`."""
        name = f"D_{base}"
        self.names[name] = np.dtype(_PRIMITIVES[base][2])
        return name

    def _structs(self, type_name: str, leaf: _Leaf, out: SourceWriter) -> None:
        """An array or sequence of structs: an N x k numpy array in one copy where the struct is k
        scalars of one type, else one call per element (its errors named by index)."""
        field = leaf.field
        fixed = field.kind == "array"
        plain = self._plain(field.nested)
        if plain is not None:
            base, width = plain
            out.line(f"if isinstance({leaf.var}, _ndarray):")
            with out.indent():
                out.line(f"pos = _numbers({leaf.var}, {self._dtype(base)}, out, pos, {type_name!r}, "
                         f"{leaf.path!r}, {fixed}, {field.count}, {width})")  # fmt: skip
            out.line("else:")
            out.depth += 1
        out.line(f"n = _count({leaf.var}, {type_name!r}, {leaf.path!r}, {fixed}, {field.count})")
        if not fixed:
            out.line("p = -pos & 3")
            out.line("out.append(_COUNT_AFTER_PAD[p].pack(n))")
            out.line("pos += p + 4")
        element = self.function(field.nested, leaf.full)
        out.line(f"for i, e in enumerate({leaf.var}):")
        with out.indent():
            index = f"{leaf.path!r} + '[%d]' % i"
            call_child(out, f"pos = {element}(e, out, pos, marks)", "EncodeError", repr(type_name), index)
            out.line("except _Unpacking:")  # a second clause of call_child's `try`
            with out.indent():
                out.line(
                    f"raise _shape_error({type_name!r}, {self.shape(field.nested)!r}, e, {index}) from None"
                )
        if plain is not None:
            out.depth -= 1

    def _plain(self, type_name: str) -> tuple[str, int] | None:
        """(primitive, how many) when every field of `type_name`, nested ones too, is a scalar or
        fixed array of one numeric primitive: its elements then lie back to back without padding."""
        bases: list[str] = []
        for field in _walk(self.structs, type_name):
            if field.kind == "sequence" or field.base not in _PRIMITIVES or field.base == "bool":
                return None
            bases += [field.base] * (field.count if field.kind == "array" else 1)
        if not bases or len(set(bases)) != 1:
            return None
        return bases[0], len(bases)


def _composer(names: list[str], default: tuple[Any, ...]) -> Any:
    """A function of a mapping of fields by name to the message's value, defaults where absent:
    generated, one `get` per field (a loop over the names costs three times as much)."""
    gets = ", ".join(f"get({name!r}, d[{index}])" for index, name in enumerate(names))
    namespace: dict[str, Any] = {"d": default}
    exec(f"def compose(fields):\n    get = fields.get\n    return ({gets},)\n", namespace)  # noqa: S102
    return namespace["compose"]


def _default(structs: Mapping[str, RosStruct], type_name: str) -> tuple[Any, ...]:
    """A message of `type_name` with ROS's defaults: zero, false, empty strings and sequences."""
    values: list[Any] = []
    for field in structs[type_name].fields:
        if field.nested:
            element: Any = _default(structs, field.nested)
        else:
            element = "" if field.base == "string" else False if field.base == "bool" else 0
        values.append(
            element if field.kind == "scalar" else [element] * field.count if field.kind == "array" else []
        )
    return tuple(values)


def _sort(leaf: _Leaf) -> str:
    """How a leaf is written: in a "run" of scalars, in a "stretch" of strings and sequences kept
    by value, or "alone" when marked (its offset is wanted each time it is written)."""
    if leaf.kind == "scalar":
        return "run"
    return "alone" if leaf.marks else "stretch"


def _key_value(leaf: _Leaf) -> str:
    """A stretch leaf's part of the stretch's key. Bytes (an image's, a mesh file's) only when
    empty: hashing them to look them up would cost more than writing them; any other value there
    makes the key unhashable (`_UNKEPT`), and the stretch is written leaf by leaf."""
    if leaf.kind == "numbers" and leaf.field.base in _BYTE_BASES:
        return f"({leaf.var} if type({leaf.var}) is bytes and not {leaf.var} else _UNKEPT)"
    return leaf.var


def _walk(structs: Mapping[str, RosStruct], type_name: str) -> Iterator[RosField]:
    """The fields of `type_name`, nested single structs replaced by theirs; a nested struct that
    is an array or sequence is one field (with no primitive base)."""
    for field in structs[type_name].fields:
        if field.nested and field.kind == "scalar":
            yield from _walk(structs, field.nested)
        else:
            yield field


def _kind(field: RosField) -> str:
    if field.base in ("string", "wstring"):
        if field.base == "wstring":
            raise SchemaError("<ros writer>", 0, f"field {field.name}: wstring is not written")
        return "string" if field.kind == "scalar" else "strings"
    if field.nested:
        return "structs"
    if field.kind == "scalar" or (field.kind == "array" and field.count <= _RUN_ARRAY_MAX):
        return "scalar"
    return "numbers"


def _with_mark(leaf: _Leaf, path: str) -> _Leaf:
    return _Leaf(leaf.kind, leaf.var, leaf.path, leaf.full, leaf.field, (*leaf.marks, path))


# --- what the generated code calls ------------------------------------------------------------


_Unpacking = (TypeError, ValueError)  # a value that does not unpack into its type's fields


# Texts -> their CDR strings at each position modulo 4 (padding to 4, uint32 length counting the
# NUL, the UTF-8 bytes, the NUL): the frame ids, namespaces and empty strings a scene writes over
# and over are encoded once. Up to `_TEXTS_KEPT` texts of `_TEXT_KEPT_BYTES` at most (4 MB at
# worst, tens of kB for a scene's names); then the cache starts over.
_TEXTS: dict[str, list[bytes]] = {}
_TEXTS_KEPT = 4096
_TEXT_KEPT_BYTES = 256
_NOT_KEPT = (KeyError, TypeError)  # TypeError: unhashable, so no string (`_text` says so)
_NO_ITEMS = [COUNT_AFTER_PAD[-phase & 3].pack(0) for phase in range(4)]  # an empty sequence, by pos % 4


def _text(text: Any, pos: int, type_name: str, field: str) -> bytes:
    """A CDR string at `pos` (see `_TEXTS`), kept in `_TEXTS` when short."""
    if not isinstance(text, str):
        raise EncodeError(type_name, field, f"a string is expected, not {type(text).__name__}")
    try:
        data = text.encode()
    except UnicodeEncodeError as error:  # a lone surrogate
        raise EncodeError(type_name, field, f"{text!r} is not valid Unicode ({error.reason})") from None
    if b"\0" in data:
        raise EncodeError(
            type_name, field, f"{text!r} contains a NUL character, which a CDR string cannot carry"
        )
    if len(data) > _TEXT_KEPT_BYTES:
        return COUNT_AFTER_PAD[-pos & 3].pack(len(data) + 1) + data + b"\0"
    forms = [COUNT_AFTER_PAD[-phase & 3].pack(len(data) + 1) + data + b"\0" for phase in range(4)]
    _hold(_TEXTS, text, forms)
    return forms[pos & 3]


def _hold(kept: dict[Any, Any], key: Any, value: Any) -> None:
    """`kept[key] = value`, `kept` emptied first when it holds `_TEXTS_KEPT` entries: a bound
    without the cost of an LRU's bookkeeping on the hits, which are all but every lookup."""
    if len(kept) >= _TEXTS_KEPT:
        kept.clear()
    kept[key] = value


# Stretches of strings and sequences (see `_Generator._stretch`) by their values and position
# modulo 4 -> their bytes: a marker's ten empty texture, text and mesh fields are one lookup.
# Kept only when every value is a string, bytes or an empty tuple (equal values of those write
# equal bytes), up to `_TEXT_KEPT_BYTES` each and `_TEXTS_KEPT` of them, then it starts over.
_STRETCHES: dict[tuple[Any, ...], bytes] = {}
_STRETCH_MIN = 3  # leaves: two strings (a frame id and a namespace) vary too often to be worth it
_KEEPABLE = (str, bytes)
_STRETCH_NUMBERS = itertools.count()
_UNKEPT: list[Any] = []  # unhashable: a key holding it is never looked up


def _keep(key: tuple[Any, ...], out: list[Any], first: int) -> None:
    """Keep the stretch just written (`out[first:]`) under `key`: its number, values and phase."""
    for value in key[1:-1]:
        if type(value) not in _KEEPABLE and not (type(value) is tuple and not value):
            return
    data = b"".join(out[first:])
    if len(data) <= _TEXT_KEPT_BYTES:
        _hold(_STRETCHES, key, data)


def _strings(
    values: Any, out: list[Any], pos: int, type_name: str, field: str, fixed: bool, count: int
) -> int:
    n = _count(values, type_name, field, fixed, count)
    if not fixed:
        pad = -pos & 3
        out.append(COUNT_AFTER_PAD[pad].pack(n))
        pos += pad + 4
    for index, text in enumerate(values):
        try:
            data = _TEXTS[text][pos & 3]
        except _NOT_KEPT:
            data = _text(text, pos, type_name, f"{field}[{index}]")
        out.append(data)
        pos += len(data)
    return pos


def _count(values: Any, type_name: str, field: str, fixed: bool, count: int) -> int:
    """The length of an array or sequence, checked against a fixed array's length or a bound."""
    try:
        n = len(values)
    except TypeError:
        raise EncodeError(type_name, field, f"a sequence is expected, not {type(values).__name__}") from None
    return _checked_length(n, type_name, field, fixed, count)


def _checked_length(n: int, type_name: str, field: str, fixed: bool, count: int) -> int:
    """`n` elements, refused unless a fixed array's `count`, or within a bounded sequence's."""
    if fixed and n != count:
        raise EncodeError(type_name, field, f"a fixed array of {count} elements is given {n}")
    if not fixed and count and n > count:
        raise EncodeError(type_name, field, f"{n} elements, more than the sequence's bound of {count}")
    return n


def _numbers(values: Any, dtype: np.dtype[Any], out: list[Any], pos: int, type_name: str, field: str,
             fixed: bool, count: int, width: int) -> int:  # fmt: skip
    """Primitives in one copy: a primitive array or sequence (`width` 1), or a sequence of structs
    of `width` primitives each, given as an N x width array (its count is N)."""
    if dtype.kind in "iu" and dtype.itemsize == 1 and isinstance(values, bytes | bytearray | memoryview):
        data: Any = memoryview(values).cast("B")
        total = len(data)
    else:
        data = _as_array(values, dtype, type_name, field)
        total = data.size
        if width > 1 and (data.ndim != 2 or data.shape[1] != width):
            raise EncodeError(
                type_name, field, f"an N x {width} array is expected, not one of shape {data.shape}"
            )
    n = _checked_length(total // width, type_name, field, fixed, count)
    glue, step = cdr_glue(pos & 7, total, dtype.itemsize, not fixed)
    if width > 1 and not fixed:  # the count written is of structs, not of primitives
        pad = -pos & 3
        glue = COUNT_AFTER_PAD[pad].pack(n) + glue[pad + 4 :]
    out.append(glue)
    out.append(data)
    return pos + step


_SHORT = 16  # elements: a list this short is packed by `struct`, faster than through numpy


def _as_array(values: Any, dtype: np.dtype[Any], type_name: str, field: str) -> np.ndarray[Any, Any]:
    """`values` as a contiguous array of `dtype`, refusing what would change on the way: floats
    for integers, integers outside the type's range."""
    try:
        array = np.asarray(values)
    except (ValueError, TypeError) as error:
        raise EncodeError(type_name, field, f"not an array of numbers ({error})") from None
    if not array.ndim:
        raise EncodeError(type_name, field, f"a sequence of numbers is expected, not {type(values).__name__}")
    if array.dtype == dtype or not array.size:
        return np.ascontiguousarray(array, dtype=dtype)
    if dtype.kind in "biu":
        if array.dtype.kind not in "biu":
            if isinstance(values, np.ndarray):
                raise EncodeError(type_name, field, f"integers are expected, not {array.dtype}")
            array = _python_ints(values, type_name, field)  # numpy made floats or objects of them
        low, high = (0, 1) if dtype.kind == "b" else (np.iinfo(dtype).min, np.iinfo(dtype).max)
        if array.min() < low or array.max() > high:
            raise EncodeError(type_name, field, f"a value is outside {dtype.name}'s range {low}..{high}")
    elif array.dtype.kind not in "biuf":
        raise EncodeError(type_name, field, f"numbers are expected, not {array.dtype}")
    return np.ascontiguousarray(array, dtype=dtype)


def _python_ints(values: Any, type_name: str, field: str) -> np.ndarray[Any, Any]:
    """Python integers that numpy would not hold as one integer type (uint64's top half beside
    small ones) as an array of objects, for the range check."""
    if not all(isinstance(value, int) for value in values):
        raise EncodeError(type_name, field, "integers are expected")
    return np.array(values, dtype=object)


def _run_error(
    type_name: str, leaves: tuple[tuple[str, str, int], ...], values: tuple[Any, ...]
) -> EncodeError:
    """The error for a run that would not pack: the first of its values that does not fit its field."""
    for (path, base, count), value in zip(leaves, values, strict=True):
        code = _PRIMITIVES[base][0]
        try:
            if count:
                _count(value, type_name, path, True, count)
                struct.pack(f"<{count}{code}", *value)
            else:
                struct.pack("<" + code, value)
        except EncodeError:
            raise
        except _PACK_ERRORS as error:
            return EncodeError(type_name, path, f"{value!r} is no {base} ({error})")
    return EncodeError(type_name, leaves[0][0], "the values do not pack")


def _shape_error(type_name: str, shape: Any, value: Any, path: str) -> EncodeError:
    """The error for a value that does not unpack as its type's fields (`shape`): where, and why."""
    found = _shape_problem(shape, value, path)
    if found is None:
        return EncodeError(type_name, path or "(message)", "the value does not unpack into the type's fields")
    return EncodeError(type_name, *found)


def _shape_problem(shape: Any, value: Any, path: str) -> tuple[str, str] | None:
    names = [name for name, _ in shape]
    if not isinstance(value, tuple | list) or len(value) != len(names):
        got = f"{len(value)} values" if isinstance(value, tuple | list) else f"a {type(value).__name__}"
        return path or "(message)", f"expects the fields ({', '.join(names)}), got {got}"
    for (name, nested), item in zip(shape, value, strict=True):
        if nested is not None:
            found = _shape_problem(nested, item, f"{path}.{name}" if path else name)
            if found is not None:
                return found
    return None


_HELPERS: dict[str, object] = {
    "EncodeError": EncodeError,
    "_PACK_ERRORS": _PACK_ERRORS,
    "_Unpacking": _Unpacking,
    "_COUNT_AFTER_PAD": COUNT_AFTER_PAD,
    "_TEXTS": _TEXTS,
    "_NOT_KEPT": _NOT_KEPT,
    "_text": _text,
    "_NO_ITEMS": _NO_ITEMS,
    "_STRETCHES": _STRETCHES,
    "_keep": _keep,
    "_UNKEPT": _UNKEPT,
    "_strings": _strings,
    "_numbers": _numbers,
    "_count": _count,
    "_run_error": _run_error,
    "_shape_error": _shape_error,
    "_ndarray": np.ndarray,
}
