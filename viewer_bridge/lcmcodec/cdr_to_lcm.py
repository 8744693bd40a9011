"""ROS 2 CDR bytes -> LCM bytes, with code generated per type and compiled once: `cdr.py` backwards.

One generator for both mappings that end in LCM: the LCM types' own ROS 2 form (docs/PROTOCOLS.md,
"Any LCM type": `compile_encoders`) and the ROS 2 types mapped onto LCM (`from_ros`, section 14:
`ros_cdr.compile_ros_encoders`). Either is given as wire structs (`RosStruct`: each field's ROS 2
primitive or nested type, scalar, fixed array or sequence); what differs is said by the fields: a
sequence of an LCM type has LCM length fields its count must equal (`RosField.lengths`), a mapped
ROS 2 sequence has none and its count becomes one; a ROS 2 type may have unsigned integers, which
widen, and wstrings.

The generated function of a struct reads the CDR of its ROS 2 message and appends LCM's
big-endian encoding to a list of byte chunks, joined once at the end behind the fingerprint. A
run of scalars is one `struct` unpack (its padding chosen by the CDR position modulo 8) and one
big-endian pack; a primitive array is one byte-swapped copy (shared with `cdr.py`), or one
widening numpy cast (uint16, uint32, uint64); a byte array a slice; a string array one pass with
one UTF-8 check. Nothing builds a Python message.

What ROS 2 may send that LCM cannot take is refused with a `DecodeError` naming the type, the
field path (ROS 2 names: the CDR speaks ROS) and the byte offset (counted from the first byte
after the 4-byte encapsulation header):
- a header other than little-endian CDR (`00 01`; the two option bytes are not read);
- too few bytes for a field, or bytes left over (up to 3 bytes that pad the whole message to a
  multiple of 4 are allowed: rclpy's `serialize_message` writes them);
- LCM's length fields: the element count of every sequence must equal the product of its LCM
  dimensions, each length field's value for a variable one and the literal for a fixed one
  (`grid[rows][cols]` holds exactly rows × cols), and no length field may be negative; a
  sequence count that could not fit in the bytes left is refused before anything is allocated;
- a string whose length is 0 (no room for its NUL), without its NUL, or not UTF-8. A NUL inside
  a string passes: LCM's length word counts every byte, lcm-gen's Python, C++ and Java keep it
  (only the C binding's `char *` ends there), and `cdr.py` carries it the other way;
- a bool byte other than 0 or 1: Fast CDR refuses those too, and one is a sign that the bytes
  are not the message they claim to be, which LCM (reading any non-zero byte as true) would hide.
"""

from __future__ import annotations

import functools
import math
import struct
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec import codegen
from viewer_bridge.lcmcodec.codegen import U32_LE, Buffer, SourceWriter, aligned_starts, string_stop
from viewer_bridge.lcmcodec.from_ros import RosField, RosStruct
from viewer_bridge.lcmcodec.layout import Layout, LayoutKeeper, learn_lcm_layout
from viewer_bridge.lcmcodec.rosnames import field_name
from viewer_bridge.lcmcodec.schema import StructDef

_CDR_LE = b"\x00\x01"
_HEADER = 4
# ROS 2 primitive -> (CDR size, little-endian struct code, LCM's big-endian struct code). A float32
# moves as its raw bits ("I"): through a Python float a signalling NaN would turn quiet.
WIRE: Mapping[str, tuple[int, str, str]] = {
    "bool": (1, "B", "B"), "byte": (1, "B", "B"), "char": (1, "B", "B"), "uint8": (1, "B", "B"),
    "int8": (1, "b", "b"), "int16": (2, "h", "h"), "uint16": (2, "H", "i"), "int32": (4, "i", "i"),
    "uint32": (4, "I", "q"), "int64": (8, "q", "q"), "uint64": (8, "Q", "q"), "float32": (4, "I", "I"),
    "float64": (8, "d", "d"),
}  # fmt: skip
# An LCM primitive's ROS 2 form (docs/PROTOCOLS.md, "Any LCM type").
_ROS_OF_LCM = {"int8_t": "int8", "int16_t": "int16", "int32_t": "int32", "int64_t": "int64", "float": "float32",
               "double": "float64", "boolean": "bool", "byte": "byte", "string": "string"}  # fmt: skip
# numpy's names for the widened ones: (CDR little-endian, LCM big-endian).
_WIDENED = {
    name: (np.dtype(f"<{WIRE[name][1]}"), np.dtype(f">{WIRE[name][2]}"))
    for name in ("uint16", "uint32", "uint64")
}
_UINT64_LIMIT = 1 << 63
# the largest value LCM takes, where CDR's type allows more
_LIMITS = {"bool": 1, "uint64": _UINT64_LIMIT - 1}
_COUNT_LIMIT = (1 << 31) - 1  # LCM's int32_t length field
_TEXT_MIN = {"string": 5, "wstring": 4}  # count and NUL; count only
_U32_BE = struct.Struct(">I").pack
_I32_BE = struct.Struct(">i").pack
_NOT_BOOL = bytes(range(2))  # what `translate` deletes from a bool array: anything left is not 0 or 1


class LcmEncoder(LayoutKeeper):
    """The compiled CDR -> LCM path of one type.

    After a message has passed the generated code, its layout (`layout`) is kept by size: a
    message of the same size and shape (header, counts, length fields, string lengths) is one
    unpack of every value, one comparison, its bools and strings checked, and one pack. Anything
    else takes the generated code, which finds and names what is wrong."""

    def __init__(self, type_name: str, packed_fingerprint: bytes, body: Callable[[Any, int, int, list[Any]], int],
                 learn: Callable[[bytes], Layout | None] | None = None) -> None:  # fmt: skip
        super().__init__(learn)
        self.type_name = type_name
        self.packed_fingerprint = packed_fingerprint
        self._body = body

    # A whole CDR message (encapsulation header first) as the whole LCM message. `convert` itself,
    # not a method calling it: the fast path is a few calls, one more shows.
    encode = LayoutKeeper.convert

    def _encode(self, data: Buffer) -> bytes:
        """The generated code's way: every check, every error named."""
        view = memoryview(data).cast("B") if type(data) is not bytes else memoryview(data)
        total = len(view)
        if total < _HEADER:
            raise DecodeError(self.type_name, "<header>", 0, f"truncated: {total} bytes, a CDR header is 4")
        representation = bytes(view[:2])
        if representation != _CDR_LE:
            kind = (
                "big-endian CDR"
                if representation == b"\x00\x00"
                else f"representation {representation.hex()}"
            )
            raise DecodeError(
                self.type_name, "<header>", 0, f"{kind}: only little-endian CDR (00 01) is read"
            )
        buf = view[_HEADER:]
        end = total - _HEADER
        out: list[Any] = [self.packed_fingerprint]
        codegen.new_message()  # the previous message's swapped arrays were copied into its LCM bytes
        offset = self._body(buf, 0, end, out)
        # rclpy pads the whole message to a multiple of 4 bytes: those few bytes are not content.
        if offset != end and not (end - offset < 4 and total % 4 == 0):
            raise DecodeError(self.type_name, "<end>", offset, f"{end - offset} trailing bytes")
        return b"".join(out)

    _convert = _encode


# --- what the generated code calls when something is wrong, or for whole values ----------------------


def _value_error(type_name: str, field: str, offset: int, base: str, value: int) -> DecodeError:
    if base == "bool":
        return DecodeError(type_name, field, offset, f"bool byte {value} is neither 0 nor 1")
    return DecodeError(
        type_name, field, offset, f"uint64 {value} does not fit LCM's int64_t (from 2^63 up: refused)"
    )


def _run_error(type_name: str, layout: tuple[tuple[str, str, int], ...], values: tuple[int, ...] | None,
               off: int, end: int) -> DecodeError:  # fmt: skip
    """What is wrong in a run of scalars at `off`: the first field cut short, or the first bool that
    is not 0/1 or uint64 from 2^63. `layout` holds (field, ROS 2 type, offset in the run) per field."""
    for index, (field, base, start) in enumerate(layout):
        size = WIRE[base][0]
        if off + start + size > end:
            return codegen.truncated(type_name, field, off + start, size, end)
        if values is not None and values[index] > _LIMITS.get(base, values[index]):
            return _value_error(type_name, field, off + start, base, values[index])
    raise AssertionError("nothing wrong in the run")  # the caller found something


def _bools(type_name: str, field: str, buf: Any, off: int, count: int) -> bytes:
    """`count` CDR bools at `off`, which LCM writes the same way, each checked to be 0 or 1."""
    chunk = bytes(buf[off : off + count])
    if chunk.translate(None, _NOT_BOOL):
        index = next(i for i, value in enumerate(chunk) if value > 1)
        raise _value_error(type_name, f"{field}[{index}]", off + index, "bool", chunk[index])
    return chunk


def _widened(type_name: str, field: str, buf: Any, off: int, count: int, base: str) -> object:
    """`count` unsigned integers of ROS 2 type `base` as LCM's next signed type (a uint64 from 2^63
    up refused)."""
    little, big = _WIDENED[base]
    values = np.frombuffer(buf, little, count, off)
    if base == "uint64":
        bad = np.flatnonzero(values > _LIMITS[base])
        if bad.size:
            index = int(bad[0])
            raise _value_error(type_name, f"{field}[{index}]", off + index * 8, base, int(values[index]))
    return values.astype(big)


def _length_error(type_name: str, field: str, offset: int, count: int, names: tuple[str, ...],
                  sizes: tuple[int, ...]) -> DecodeError:  # fmt: skip
    """A sequence whose count is not what LCM's length fields (and literal dimensions) say."""
    for name, size in zip(names, sizes, strict=True):
        if size < 0 and not name.isdigit():
            return DecodeError(type_name, field, offset, f"length field {name} is negative ({size})")
    expected = math.prod(sizes)
    if len(sizes) == 1:
        said = f"{names[0]} = {sizes[0]}" if not names[0].isdigit() else f"its size {sizes[0]}"
    else:
        said = f"{' × '.join(names)} = {' × '.join(map(str, sizes))} = {expected}"
    return DecodeError(type_name, field, offset, f"has {count} elements, but {said}")


def _count(
    buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str, bound: int
) -> tuple[int, int]:
    """A sequence's CDR count (aligned to 4), checked against its bound and LCM's int32_t, written as
    the LCM length field; returns the count and the offset after it."""
    off += -off & 3
    if off + 4 > end:
        raise codegen.truncated(type_name, field, off, 4, end)
    (count,) = U32_LE(buf, off)
    if bound and count > bound:
        raise DecodeError(type_name, field, off, f"count {count} is above the sequence's bound {bound}")
    if count > _COUNT_LIMIT:
        raise DecodeError(type_name, field, off, f"count {count} does not fit LCM's int32_t length field")
    out.append(_I32_BE(count))
    return count, off + 4


def string_to_lcm(buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str) -> int:
    """One string: CDR's little-endian length (counting the NUL) to LCM's big-endian one."""
    off += -off & 3
    stop = string_stop(buf, off, end, type_name, field, U32_LE)
    out.append(_U32_BE(stop - off - 4))
    out.append(bytes(buf[off + 4 : stop]))
    return stop


def _strings(buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str, count: int) -> int:
    """`count` strings (a string array): CDR's little-endian lengths to LCM's big-endian ones, the
    bytes (with their NUL) as slices, and one UTF-8 check of them all. Each ends in its NUL, so a
    character cut at the end of one cannot pass as whole with the next. Whatever is wrong is found
    and named by `string_to_lcm`, run again on the element where it is."""
    starts, first = [], len(out)
    for index in range(count):
        off += -off & 3
        length = U32_LE(buf, off)[0] if off + 4 <= end else 0
        stop = off + 4 + length
        if length == 0 or stop > end or buf[stop - 1] != 0:
            raise _string_problem(buf, off, end, type_name, f"{field}[{index}]")
        starts.append(off)
        out.append(_U32_BE(length))
        out.append(buf[off + 4 : stop])
        off = stop
    try:
        str(b"".join(out[first + 1 :: 2]), "utf-8")
    except UnicodeDecodeError:
        for index, start in enumerate(starts):
            string_to_lcm(buf, start, end, [], type_name, f"{field}[{index}]")
    return off


def _string_problem(buf: Any, off: int, end: int, type_name: str, field: str) -> DecodeError:
    """The error `string_to_lcm` raises for the string at `off`, which is known to be wrong."""
    try:
        string_to_lcm(buf, off, end, [], type_name, field)
    except DecodeError as error:
        return error
    raise AssertionError(f"{field}: nothing wrong at {off}")


def _wstring(buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str) -> int:
    """A wstring as Fast DDS's type support writes it: a uint32 count of UTF-16 code units, each in
    4 bytes (wchar_t), no terminator; to LCM as UTF-8 with its NUL."""
    off += -off & 3
    if off + 4 > end:
        raise codegen.truncated(type_name, field, off, 4, end)
    count: int = U32_LE(buf, off)[0]
    start = off + 4
    if count * 4 > end - start:
        raise codegen.bad_count(type_name, field, start, count, 4, end)
    units = np.frombuffer(buf, "<u4", count, start)
    wide = np.flatnonzero(units > 0xFFFF)
    if wide.size:
        index = int(wide[0])
        raise DecodeError(
            type_name, field, start + 4 * index, f"code unit {int(units[index]):#x} is not UTF-16"
        )
    try:
        text = units.astype("<u2").tobytes().decode("utf-16-le")
    except UnicodeDecodeError as error:  # a surrogate without its pair
        raise DecodeError(
            type_name, field, start + 2 * error.start, "invalid UTF-16 (unpaired surrogate)"
        ) from None
    data = text.encode("utf-8")
    out.append(_U32_BE(len(data) + 1))
    out.append(data)
    out.append(b"\0")
    return start + 4 * count


_HELPERS: Mapping[str, object] = {
    "DecodeError": DecodeError,
    "_truncated": codegen.truncated,
    "_bad_count": codegen.bad_count,
    "_run_error": _run_error,
    "_bools": _bools,
    "_widened": _widened,
    "_length_error": _length_error,
    "_count": _count,
    "_string": string_to_lcm,
    "_strings": _strings,
    "_wstring": _wstring,
    "_U32_LE": U32_LE,
    **{f"_swap{size}": codegen.swapped(size) for size in (2, 4, 8)},
}

# The code of a run of scalars (n: its formats' name, t: the type's literal, v: its values): the
# little-endian layout for the position modulo 8 read in one unpack, checked, written in one pack.
_RUN = """k = off & 7
if off + {n}_N[k] > end:
    raise _run_error({t}, {n}_L[k], None, off, end)
{v}, = {n}_LE[k].unpack_from(buf, off)
{check}out.append({n}.pack({v}))
off += {n}_N[k]"""


# --- the mappings -----------------------------------------------------------------------------------


def lcm_wire(structs: Mapping[str, StructDef]) -> dict[str, RosStruct]:
    """The LCM types' own ROS 2 form as wire structs, by LCM full name (which the errors name):
    each member a field of its ROS 2 name; an array with one fixed size a fixed array, any other
    a sequence whose count must be the product of its LCM dimensions (`lengths`)."""
    wire = {}
    for name, definition in structs.items():
        fields = []
        for member in definition.members:
            base = _ROS_OF_LCM.get(member.type_name, "")
            nested = "" if base else member.type_name
            ros = field_name(member.name)
            if not member.dims:
                fields.append(RosField(ros, base, nested))
            elif len(member.dims) == 1 and not member.dims[0].is_variable:
                fields.append(RosField(ros, base, nested, "array", member.dims[0].count))
            else:
                lengths = tuple(
                    field_name(dim.size) if dim.is_variable else str(dim.count) for dim in member.dims
                )
                fields.append(RosField(ros, base, nested, "sequence", lengths=lengths))
        wire[name] = RosStruct(name, name, tuple(fields))
    return wire


def compile_wire(
    lcm: Mapping[str, StructDef], wire: Mapping[str, RosStruct], names: Iterable[str],
    min_sizes: Mapping[str, int] | None = None,
) -> dict[str, Callable[[Any, int, int, list[Any]], int]]:  # fmt: skip
    """The generated CDR -> LCM functions of the wire structs `names` (by the name `wire` has
    them; each names its LCM struct among `lcm`, which holds every nested one). `min_sizes`: the
    fewest CDR bytes of each wire struct, refusing counts that cannot fit; the LCM ones when None."""
    by_lcm = {struct_.lcm_name: struct_ for struct_ in wire.values()}
    lcm_names = [wire[name].lcm_name for name in names]
    generator = functools.partial(_Generator, by_lcm, min_sizes)
    bodies = codegen.compile_generated(lcm, lcm_names, "C", generator, _HELPERS, "<cdr -> lcm encoders>")
    return {name: bodies[wire[name].lcm_name] for name in names}


def compile_encoders(
    structs: Mapping[str, StructDef], fingerprints: Mapping[str, bytes], names: Iterable[str]
) -> dict[str, LcmEncoder]:
    """The CDR -> LCM encoders of LCM types `names` (every nested type is in `structs`)."""
    names = list(names)
    bodies = compile_wire(structs, lcm_wire(structs), names)
    return {name: LcmEncoder(name, fingerprints[name], body,
                             functools.partial(learn_lcm_layout, structs, name, fingerprint=fingerprints[name]))
            for name, body in bodies.items()}  # fmt: skip


# --- the generator ----------------------------------------------------------------------------------


def _element_min(ros_field: RosField, sizes: Mapping[str, int]) -> int:
    """The fewest CDR bytes of one element of `ros_field` (`sizes`: each nested struct's)."""
    if ros_field.nested:
        return sizes[ros_field.nested]
    return _TEXT_MIN.get(ros_field.base) or WIRE[ros_field.base][0]


class _Generator:
    """Writes the CDR -> LCM function of one struct (the signature `compile_generated` calls)."""

    def __init__(self, by_lcm: Mapping[str, RosStruct], wire_min_sizes: Mapping[str, int] | None,
                 struct_: StructDef, idents: Mapping[str, str], lcm_min_sizes: Mapping[str, int],
                 out: SourceWriter, formats: dict[str, object]) -> None:  # fmt: skip
        self.wire = by_lcm[struct_.full_name]
        self.lcm_of = {wire.ros_name: lcm_name for lcm_name, wire in by_lcm.items()}
        self.min_sizes = lcm_min_sizes if wire_min_sizes is None else wire_min_sizes
        self.idents = idents
        self.out = out
        self.formats = formats
        self.ident = idents[struct_.full_name]
        self.t = repr(self.wire.ros_name)
        self.indices = {ros_field.name: index for index, ros_field in enumerate(self.wire.fields)}

    def write(self) -> None:
        out = self.out
        out.line(f"def {self.ident}(buf, off, end, out):")
        with out.indent():
            if not self.wire.fields:  # ROS 2 gives an empty message one uint8; LCM writes nothing
                out.line("if off + 1 > end:")
                with out.indent():
                    out.line(
                        f"raise _truncated({self.t}, 'structure_needs_at_least_one_member', off, 1, end)"
                    )
                out.line("off += 1")
            run: list[tuple[int, RosField]] = []
            for index, ros_field in enumerate(self.wire.fields):
                if ros_field.kind == "scalar" and ros_field.base in WIRE:
                    run.append((index, ros_field))
                    continue
                if run:
                    self.scalars(run)
                    run = []
                self.field(ros_field)
            if run:
                self.scalars(run)
            out.line("return off")

    def scalars(self, run: list[tuple[int, RosField]]) -> None:
        """Scalars in a row: one unpack of the layout for `off % 8`, the checks, one pack. Each
        value is `v<index>` (a length field's is read by the sequences it sizes)."""
        name = f"{self.ident}_S{len(self.formats)}"
        self.formats[name] = struct.Struct(">" + "".join(WIRE[f.base][2] for _, f in run))
        sizes = [WIRE[f.base][0] for _, f in run]
        readers, layouts = [], []
        for phase in range(8):
            starts = aligned_starts(phase, sizes)
            ends = [0] + [start + size for start, size in zip(starts, sizes, strict=True)][:-1]
            codes = (
                f"{start - before}x{WIRE[f.base][1]}"
                for start, before, (_, f) in zip(starts, ends, run, strict=True)
            )
            readers.append(struct.Struct("<" + "".join(codes)))
            layouts.append(tuple((f.name, f.base, start) for (_, f), start in zip(run, starts, strict=True)))
        self.formats[name + "_LE"] = readers
        self.formats[name + "_N"] = [reader.size for reader in readers]
        self.formats[name + "_L"] = layouts
        values = ", ".join(f"v{index}" for index, _ in run)
        checks = " or ".join(f"v{i} > {_LIMITS[f.base]}" for i, f in run if f.base in _LIMITS)
        check = (
            f"if {checks}:\n    raise _run_error({self.t}, {name}_L[k], ({values},), off, end)\n"
            if checks
            else ""
        )
        for line in _RUN.format(n=name, t=self.t, v=values, check=check).splitlines():
            self.out.line(line)

    def field(self, ros_field: RosField) -> None:
        out = self.out
        name = repr(ros_field.name)
        if ros_field.kind == "scalar":
            self.element(ros_field, name)
            return
        if ros_field.kind == "array":
            out.line(f"n = {ros_field.count}")
        elif ros_field.lengths:
            self.lcm_count(ros_field)
        else:
            out.line(f"n, off = _count(buf, off, end, out, {self.t}, {name}, {ros_field.count})")
        if ros_field.base in WIRE:
            self.numbers(ros_field)
            return
        element = max(_element_min(ros_field, self.min_sizes), 1)
        out.line(f"if n * {element} > end - off:")
        with out.indent():
            out.line(f"raise _bad_count({self.t}, {name}, off, n, {element}, end)")
        if ros_field.base == "string":
            out.line(f"off = _strings(buf, off, end, out, {self.t}, {name}, n)")
            return
        out.line("for i in range(n):")
        with out.indent():
            self.element(ros_field, f"'{ros_field.name}[%d]' % i")

    def lcm_count(self, ros_field: RosField) -> None:
        """A sequence's CDR count, which must be what its LCM dimensions say (LCM has them already)."""
        out, name = self.out, repr(ros_field.name)
        sizes = [f"v{self.indices[size]}" if not size.isdigit() else size for size in ros_field.lengths]
        negative = [f"{size} < 0" for size in sizes if not size.isdigit()]
        out.line("off += -off & 3")
        out.line("if off + 4 > end:")
        with out.indent():
            out.line(f"raise _truncated({self.t}, {name}, off, 4, end)")
        out.line("(n,) = _U32_LE(buf, off)")
        expected, listed = " * ".join(sizes), ", ".join(sizes)
        out.line(f"if {' or '.join([f'n != {expected}', *negative])}:")
        with out.indent():
            out.line(f"raise _length_error({self.t}, {name}, off, n, {ros_field.lengths!r}, ({listed},))")
        out.line("off += 4")

    def numbers(self, ros_field: RosField) -> None:
        """`n` primitives: aligned when there are any, counted against the bytes left, then one copy."""
        out, name, base = self.out, repr(ros_field.name), ros_field.base
        size = WIRE[base][0]
        if size > 1:
            out.line(f"if n: off += -off & {size - 1}")
        out.line(f"if n * {size} > end - off:")
        with out.indent():
            out.line(f"raise _bad_count({self.t}, {name}, off, n, {size}, end)")
        if base == "bool":
            out.line(f"out.append(_bools({self.t}, {name}, buf, off, n))")
        elif size == 1:
            out.line("out.append(buf[off:off + n])")
        elif base in _WIDENED:
            out.line(f"out.append(_widened({self.t}, {name}, buf, off, n, {base!r}))")
        else:  # the same width both sides: the bytes reversed
            out.line(f"out.append(_swap{size}(buf, off, n))")
        out.line(f"off += n * {size}")

    def element(self, ros_field: RosField, field: str) -> None:
        if ros_field.base in ("string", "wstring"):
            helper = "_string" if ros_field.base == "string" else "_wstring"
            self.out.line(f"off = {helper}(buf, off, end, out, {self.t}, {field})")
            return
        child = self.idents[self.lcm_of[ros_field.nested]]
        codegen.call_child(self.out, f"off = {child}(buf, off, end, out)", "DecodeError", self.t, field)
