"""ROS 2 CDR -> LCM for any ROS 2 type mapped by `from_ros` (docs/PROTOCOLS.md section 14).

Code is generated per type and compiled once, as `cdr_to_lcm` does for the LCM types' own ROS 2
mapping, and run by the same `LcmEncoder` (header, trailing bytes). What differs is the mapping
itself: here the CDR is the ROS 2 type's, and LCM gets what ROS 2 does not send, a length field
before each sequence, and wider integers for the unsigned ones LCM lacks. A run of scalars is one
little-endian `struct` unpack (its padding chosen by the CDR position modulo 8) and one big-endian
pack; a primitive array one byte-swapped copy (Python's array when short, numpy when long or
widened: uint16/uint32); a byte array a slice; a string array one pass with one UTF-8 check.
Nothing builds a Python message. Once a message has passed that code, its layout is kept
(`layout`): the next of the same shape is one call of the compiled mover.

Errors are `DecodeError`s with the ROS 2 type, the field path and the byte offset (from the
first byte after the 4-byte encapsulation header).
"""

from __future__ import annotations

import functools
import struct
from array import array
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.cdr_to_lcm import LcmEncoder, string_to_lcm
from viewer_bridge.lcmcodec.codegen import SourceWriter, bad_count, call_child, compile_generated, truncated
from viewer_bridge.lcmcodec.from_ros import LcmFromRos, RosField, RosStruct
from viewer_bridge.lcmcodec.layout import learn_ros_layout
from viewer_bridge.lcmcodec.schema import StructDef

__all__ = ["compile_ros_encoders"]

# ROS 2 primitive -> (CDR size, little-endian struct code, LCM's big-endian struct code). A float32
# moves as its raw bits ("I"): through a Python float a signalling NaN would turn quiet.
_WIRE: Mapping[str, tuple[int, str, str]] = {
    "bool": (1, "B", "B"), "byte": (1, "B", "B"), "char": (1, "B", "B"), "uint8": (1, "B", "B"),
    "int8": (1, "b", "b"), "int16": (2, "h", "h"), "uint16": (2, "H", "i"), "int32": (4, "i", "i"),
    "uint32": (4, "I", "q"), "int64": (8, "q", "q"), "uint64": (8, "Q", "q"), "float32": (4, "I", "I"),
    "float64": (8, "d", "d"),
}  # fmt: skip
# numpy's names for the same: (CDR little-endian, LCM big-endian).
_DTYPES = {name: (np.dtype(f"<{le}"), np.dtype(f">{be}")) for name, (_, le, be) in _WIRE.items()}
_UINT64_LIMIT = 1 << 63
# The primitives whose LCM form is their CDR bytes reversed (the same width, no check), by an array
# typecode of their size: byteswap only needs the size.
_SWAPS = {"int16": "H", "int32": "I", "int64": "Q", "float32": "I", "float64": "Q"}
_NUMPY_FROM = 256  # elements
# the largest value LCM takes, where CDR's type allows more
_LIMITS = {"bool": 1, "uint64": _UINT64_LIMIT - 1}
_COUNT_LIMIT = (1 << 31) - 1  # LCM's int32_t length field
_TEXT_MIN = {"string": 5, "wstring": 4}  # count and NUL; count only
_U32_LE = struct.Struct("<I").unpack_from
_U32_BE = struct.Struct(">I").pack
_I32_BE = struct.Struct(">i").pack


def compile_ros_encoders(
    mapping: LcmFromRos, ros_names: Iterable[str], keep_layouts: bool = True
) -> dict[str, LcmEncoder]:
    """The CDR -> LCM encoders of the mapped ROS 2 types `ros_names`, by ROS 2 name. Each keeps the
    layouts of the messages it has converted (`layout`) unless `keep_layouts` is False: then
    every message takes the generated code (as the first of each shape does)."""
    names = list(ros_names)
    by_lcm = {struct_.lcm_name: struct_ for struct_ in mapping.structs.values()}
    helpers: dict[str, object] = {"DecodeError": DecodeError, "_truncated": truncated, "_string": string_to_lcm,
                                  "_wstring": _wstring, "_count": _count, "_numbers": _numbers,
                                  "_run_problem": _run_problem, "_room": _room,
                                  "_strings": _strings}  # fmt: skip
    lcm_names = [mapping.structs[name].lcm_name for name in names]
    generator = functools.partial(_Generator, by_lcm, _min_sizes(mapping.structs))
    bodies = compile_generated(mapping.lcm, lcm_names, "R", generator, helpers, "<ros cdr -> lcm encoders>")
    learners = {name: functools.partial(learn_ros_layout, mapping.structs, _WIRE, name, mapping.packed_fingerprint(name))
                for name in names}  # fmt: skip
    return {name: LcmEncoder(name, mapping.packed_fingerprint(name), bodies[mapping.structs[name].lcm_name],
                             learners[name] if keep_layouts else None)
            for name in names}  # fmt: skip


def _min_sizes(structs: Mapping[str, RosStruct]) -> dict[str, int]:
    """The fewest CDR bytes of each type (padding aside): the bound that refuses impossible counts."""
    sizes: dict[str, int] = {}

    def size_of(name: str) -> int:
        if name not in sizes:
            sizes[name] = sum(_field_min(f, size_of) for f in structs[name].fields)
        return sizes[name]

    for name in structs:
        size_of(name)
    return sizes


def _field_min(ros_field: RosField, size_of: Any) -> int:
    if ros_field.kind == "sequence":
        return 4
    count = ros_field.count if ros_field.kind == "array" else 1
    return count * _element_min(ros_field, size_of)


def _element_min(ros_field: RosField, size_of: Any) -> int:
    if ros_field.nested:
        return int(size_of(ros_field.nested))
    return _TEXT_MIN.get(ros_field.base) or _WIRE[ros_field.base][0]


# --- what the generated code calls -------------------------------------------------------------------


def _room(type_name: str, field: str, offset: int, count: int, size: int, end: int) -> None:
    """Refuse `count` elements of at least `size` bytes each that cannot fit before `end`."""
    if count * size > end - offset:
        raise bad_count(type_name, field, offset, count, size, end)


def _count(
    buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str, bound: int
) -> tuple[int, int]:
    """A sequence's CDR count (aligned to 4), checked against its bound and LCM's int32_t, written as
    the LCM length field; returns the count and the offset after it."""
    off += -off & 3
    if off + 4 > end:
        raise truncated(type_name, field, off, 4, end)
    (count,) = _U32_LE(buf, off)
    if bound and count > bound:
        raise DecodeError(type_name, field, off, f"count {count} is above the sequence's bound {bound}")
    if count > _COUNT_LIMIT:
        raise DecodeError(type_name, field, off, f"count {count} does not fit LCM's int32_t length field")
    out.append(_I32_BE(count))
    return count, off + 4


def _numbers(
    buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str, base: str, count: int
) -> int:
    """`count` numbers of ROS 2 type `base` at `off` (aligned first when there are any) to LCM."""
    size = _WIRE[base][0]
    if not count:
        return off
    if size > 1:
        off += -off & (size - 1)
    _room(type_name, field, off, count, size, end)
    if size == 1 and base != "bool":
        out.append(buf[off : off + count])
        return off + count
    little, big = _DTYPES[base]
    if count < _NUMPY_FROM and base in _SWAPS:  # a few numbers: Python's array swaps faster than numpy's call
        swapped = array(_SWAPS[base])
        swapped.frombytes(buf[off : off + count * size])
        swapped.byteswap()
        out.append(swapped)
        return off + count * size
    values = np.frombuffer(buf, little, count, off)
    if base in ("bool", "uint64"):
        bad = np.flatnonzero(values > _LIMITS[base])
        if bad.size:
            index = int(bad[0])
            raise _value_error(type_name, f"{field}[{index}]", off + index * size, base, int(values[index]))
    out.append(values.astype(big))
    return off + count * size


def _strings(buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str, count: int) -> int:
    """`count` strings (a string array): CDR's little-endian lengths to LCM's big-endian ones, the
    bytes (with their NUL) as slices, and one UTF-8 check of them all. Each ends in its NUL, so a
    character cut at the end of one cannot pass as whole with the next. Whatever is wrong is found
    and named by `_string`, run again on the element where it is."""
    starts, first = [], len(out)
    for index in range(count):
        off += -off & 3
        length = _U32_LE(buf, off)[0] if off + 4 <= end else 0
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


def _value_error(type_name: str, field: str, offset: int, base: str, value: int) -> DecodeError:
    if base == "bool":
        return DecodeError(type_name, field, offset, f"bool byte {value} is neither 0 nor 1")
    return DecodeError(
        type_name, field, offset, f"uint64 {value} does not fit LCM's int64_t (from 2^63 up: refused)"
    )


def _run_problem(type_name: str, layout: tuple[tuple[str, str, int], ...], values: tuple[int, ...] | None,
                 off: int, end: int) -> DecodeError:  # fmt: skip
    """What is wrong in a run of scalars at `off`: the first field cut short, or the first bool that
    is not 0/1 or uint64 from 2^63. `layout` holds (field, ROS 2 type, offset in the run) per field."""
    for index, (field, base, start) in enumerate(layout):
        size = _WIRE[base][0]
        if off + start + size > end:
            return truncated(type_name, field, off + start, size, end)
        if values is not None and values[index] > _LIMITS.get(base, values[index]):
            return _value_error(type_name, field, off + start, base, values[index])
    raise AssertionError("nothing wrong in the run")  # the caller found something


def _wstring(buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str) -> int:
    """A wstring as Fast DDS's type support writes it: a uint32 count of UTF-16 code units, each in
    4 bytes (wchar_t), no terminator; to LCM as UTF-8 with its NUL."""
    off += -off & 3
    if off + 4 > end:
        raise truncated(type_name, field, off, 4, end)
    count: int = _U32_LE(buf, off)[0]
    start = off + 4
    _room(type_name, field, start, count, 4, end)
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


def _starts(phase: int, sizes: list[int]) -> list[int]:
    """Where consecutive CDR primitives of `sizes` bytes start, counted from the first one's position,
    when that position is `phase` modulo 8 (each is aligned to its size)."""
    starts, position = [], phase
    for size in sizes:
        position += -position & (size - 1)
        starts.append(position - phase)
        position += size
    return starts


# The code of a run of scalars (n: its formats' name, t: the type's literal, v: its values): the
# little-endian layout for the position modulo 8 read in one unpack, checked, written in one pack.
_RUN = """k = off & 7
if off + {n}_N[k] > end:
    raise _run_problem({t}, {n}_L[k], None, off, end)
{v}, = {n}_LE[k].unpack_from(buf, off)
{check}out.append({n}.pack({v}))
off += {n}_N[k]"""


# --- the generator ----------------------------------------------------------------------------------


class _Generator:
    """Writes the CDR -> LCM function of one struct (the signature `compile_generated` calls)."""

    def __init__(self, by_lcm: Mapping[str, RosStruct], min_sizes: Mapping[str, int], struct_: StructDef,
                 idents: Mapping[str, str], _lcm_min_sizes: Mapping[str, int], out: SourceWriter,
                 formats: dict[str, object]) -> None:  # fmt: skip
        self.ros = by_lcm[struct_.full_name]
        self.by_lcm = by_lcm
        self.min_sizes = min_sizes
        self.idents = idents
        self.out = out
        self.formats = formats
        self.ident = idents[struct_.full_name]
        self.t = repr(self.ros.ros_name)

    def write(self) -> None:
        self.out.line(f"def {self.ident}(buf, off, end, out):")
        with self.out.indent():
            run: list[RosField] = []
            for ros_field in self.ros.fields:
                if ros_field.kind == "scalar" and ros_field.base in _WIRE:
                    run.append(ros_field)
                    continue
                if run:
                    self.scalars(run)
                    run = []
                self.field(ros_field)
            if run:
                self.scalars(run)
            self.out.line("return off")

    def scalars(self, run: list[RosField]) -> None:
        """Scalars in a row: one unpack of the layout for `off % 8`, the checks, one pack."""
        out = self.out
        name = f"{self.ident}_S{len(self.formats)}"
        self.formats[name] = struct.Struct(">" + "".join(_WIRE[f.base][2] for f in run))
        sizes = [_WIRE[f.base][0] for f in run]
        readers, layouts = [], []
        for phase in range(8):
            starts = _starts(phase, sizes)
            ends = [0] + [start + size for start, size in zip(starts, sizes, strict=True)][:-1]
            codes = (
                f"{start - before}x{_WIRE[f.base][1]}"
                for start, before, f in zip(starts, ends, run, strict=True)
            )
            readers.append(struct.Struct("<" + "".join(codes)))
            layouts.append(tuple((f.name, f.base, start) for f, start in zip(run, starts, strict=True)))
        self.formats[name + "_LE"] = readers
        self.formats[name + "_N"] = [reader.size for reader in readers]
        self.formats[name + "_L"] = layouts
        values = ", ".join(f"v{index}" for index in range(len(run)))
        checks = " or ".join(f"v{i} > {_LIMITS[f.base]}" for i, f in enumerate(run) if f.base in _LIMITS)
        check = (
            f"if {checks}:\n    raise _run_problem({self.t}, {name}_L[k], ({values},), off, end)\n"
            if checks
            else ""
        )
        for line in _RUN.format(n=name, t=self.t, v=values, check=check).splitlines():
            out.line(line)

    def field(self, ros_field: RosField) -> None:
        out = self.out
        name = repr(ros_field.name)
        if ros_field.kind == "scalar":
            self.element(ros_field, name)
            return
        if ros_field.kind == "sequence":
            out.line(f"n, off = _count(buf, off, end, out, {self.t}, {name}, {ros_field.count})")
        else:
            out.line(f"n = {ros_field.count}")
        if ros_field.base in _WIRE:
            out.line(f"off = _numbers(buf, off, end, out, {self.t}, {name}, {ros_field.base!r}, n)")
            return
        if ros_field.base == "string":
            out.line(f"_room({self.t}, {name}, off, n, 5, end)")
            out.line(f"off = _strings(buf, off, end, out, {self.t}, {name}, n)")
            return
        element = max(_element_min(ros_field, self.min_sizes.__getitem__), 1)
        out.line(f"_room({self.t}, {name}, off, n, {element}, end)")
        out.line("for i in range(n):")
        with out.indent():
            self.element(ros_field, f"'{ros_field.name}[%d]' % i")

    def element(self, ros_field: RosField, field: str) -> None:
        if ros_field.base in ("string", "wstring"):
            helper = "_string" if ros_field.base == "string" else "_wstring"
            self.out.line(f"off = {helper}(buf, off, end, out, {self.t}, {field})")
            return
        child = self.idents[self.by_lcm_name(ros_field.nested)]
        call_child(self.out, f"off = {child}(buf, off, end, out)", "DecodeError", self.t, field)

    def by_lcm_name(self, ros_name: str) -> str:
        return next(name for name, struct_ in self.by_lcm.items() if struct_.ros_name == ros_name)
