"""ROS 2 CDR bytes -> LCM bytes, with code generated per type and compiled once: `cdr.py` backwards.

The generated function of a struct reads the CDR of its ROS 2 message (docs/PROTOCOLS.md, "Any
LCM type") and appends LCM's big-endian encoding to a list of byte chunks, joined once at the end
behind the fingerprint. A run of scalars is one `struct` unpack (its padding chosen by the CDR
position modulo 8) and one big-endian pack; a primitive array is one byte-swapped copy (shared
with `cdr.py`); a byte array a slice.

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

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec import codegen
from viewer_bridge.lcmcodec.codegen import U32_LE, Buffer, StructWriter, scalar_runs, string_stop
from viewer_bridge.lcmcodec.layout import Layout, LayoutKeeper, learn_lcm_layout
from viewer_bridge.lcmcodec.rosnames import field_name
from viewer_bridge.lcmcodec.schema import PRIMITIVE_FORMATS, Member, StructDef

_CDR_LE = b"\x00\x01"
_HEADER = 4
# How a scalar is read and written: as itself, except a float32, which goes as its raw bits (Python
# would widen it to a double and back, which turns a signalling NaN into a quiet one).
_CODES = {"int8_t": "b", "int16_t": "h", "int32_t": "i", "int64_t": "q", "float": "I", "double": "d",
          "boolean": "B", "byte": "B"}  # fmt: skip
_U32_BE = struct.Struct(">I").pack
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


def _run_error(type_name: str, layout: tuple[tuple[str, int, int, bool], ...], values: tuple[int, ...] | None,
               off: int, end: int) -> DecodeError:  # fmt: skip
    """The error of a run of scalars at `off`: the first field cut short, or the first bool not 0/1.
    `layout` holds (field, offset in the run, size, is bool) per field."""
    for index, (field, start, size, is_bool) in enumerate(layout):
        if off + start + size > end:
            return codegen.truncated(type_name, field, off + start, size, end)
        if values is not None and is_bool and values[index] > 1:
            return _not_bool(type_name, field, off + start, values[index])
    raise AssertionError("nothing wrong in the run")  # the caller found something


def _not_bool(type_name: str, field: str, offset: int, value: int) -> DecodeError:
    return DecodeError(type_name, field, offset, f"bool byte {value} is neither 0 nor 1")


def _bools(type_name: str, field: str, buf: Any, off: int, count: int) -> bytes:
    """`count` CDR bools at `off`, which LCM writes the same way, each checked to be 0 or 1."""
    chunk = bytes(buf[off : off + count])
    if chunk.translate(None, _NOT_BOOL):
        index = next(i for i, value in enumerate(chunk) if value > 1)
        raise _not_bool(type_name, f"{field}[{index}]", off + index, chunk[index])
    return chunk


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


def string_to_lcm(buf: Any, off: int, end: int, out: list[Any], type_name: str, field: str) -> int:
    """One string: CDR's little-endian length (counting the NUL) to LCM's big-endian one."""
    off += -off & 3
    stop = string_stop(buf, off, end, type_name, field, U32_LE)
    out.append(_U32_BE(stop - off - 4))
    out.append(bytes(buf[off + 4 : stop]))
    return stop


class _Generator(StructWriter):
    """Writes the CDR -> LCM function of one struct."""

    def write(self) -> None:
        out = self.out
        out.line(f"def {self.ident}(buf, off, end, out):")
        with out.indent():
            if not self.struct.members:  # ROS 2 gives an empty message one uint8; LCM writes nothing
                out.line("if off + 1 > end:")
                with out.indent():
                    out.line(
                        f"raise _truncated({self.t}, 'structure_needs_at_least_one_member', off, 1, end)"
                    )
                out.line("off += 1")
            for scalars, run in scalar_runs(self.struct):
                if scalars:
                    self.scalars(run)
                else:
                    self.member(*run[0])
            out.line("return off")

    def scalars(self, run: list[tuple[int, Member]]) -> None:
        """Fixed scalars: one little-endian unpack padded for `off % 8`, bools checked, one pack."""
        out = self.out
        name = f"{self.ident}_S{len(self.formats)}"
        self.formats[name] = struct.Struct(">" + "".join(_CODES[m.type_name] for _, m in run))
        unpackers, layouts = [], []
        for phase in range(8):
            fmt, position, layout = "<", phase, []
            for _, member in run:
                size = PRIMITIVE_FORMATS[member.type_name][1]
                pad = -position & (size - 1)
                fmt += "x" * pad + _CODES[member.type_name]
                layout.append(
                    (field_name(member.name), position + pad - phase, size, member.type_name == "boolean")
                )
                position += pad + size
            unpackers.append(struct.Struct(fmt))
            layouts.append(tuple(layout))
        self.formats[name + "_LE"] = unpackers
        self.formats[name + "_N"] = [unpacker.size for unpacker in unpackers]
        self.formats[name + "_L"] = layouts
        values = ", ".join(f"v{index}" for index, _ in run)
        out.line("k = off & 7")
        out.line(f"if off + {name}_N[k] > end:")
        with out.indent():
            out.line(f"raise _run_error({self.t}, {name}_L[k], None, off, end)")
        out.line(f"{values}{',' if len(run) == 1 else ''} = {name}_LE[k].unpack_from(buf, off)")
        bools = [f"v{index} > 1" for index, member in run if member.type_name == "boolean"]
        if bools:
            out.line(f"if {' or '.join(bools)}:")
            with out.indent():
                out.line(f"raise _run_error({self.t}, {name}_L[k], ({values},), off, end)")
        out.line(f"out.append({name}.pack({values}))")
        out.line(f"off += {name}_N[k]")

    def member(self, index: int, member: Member) -> None:
        ros = field_name(member.name)
        if not member.dims:
            self.element(member, repr(ros))
            return
        out = self.out
        fixed = len(member.dims) == 1 and not member.dims[0].is_variable
        element = max(codegen.element_min_size(member, self.min_sizes), 1)
        if fixed:
            out.line(f"n = {member.dims[0].count}")
        else:
            names = tuple(field_name(dim.size) if dim.is_variable else str(dim.count) for dim in member.dims)
            sizes = ", ".join(
                f"v{self.index_of(dim.size)}" if dim.is_variable else str(dim.count) for dim in member.dims
            )
            expected = " * ".join(
                f"v{self.index_of(dim.size)}" if dim.is_variable else str(dim.count) for dim in member.dims
            )
            negative = [f"v{self.index_of(dim.size)} < 0" for dim in member.dims if dim.is_variable]
            out.line("off += -off & 3")
            out.line("if off + 4 > end:")
            with out.indent():
                out.line(f"raise _truncated({self.t}, {ros!r}, off, 4, end)")
            out.line("(n,) = _U32_LE(buf, off)")
            check = f"n != {expected}" + "".join(f" or {test}" for test in negative)
            out.line(f"if {check}:")
            with out.indent():
                out.line(f"raise _length_error({self.t}, {ros!r}, off, n, {names!r}, ({sizes},))")
            out.line("off += 4")
        if member.type_name in PRIMITIVE_FORMATS:
            size = PRIMITIVE_FORMATS[member.type_name][1]
            if size > 1:
                out.line(f"if n: off += -off & {size - 1}")
            out.line(f"if n * {size} > end - off:")
            with out.indent():
                out.line(f"raise _bad_count({self.t}, {ros!r}, off, n, {size}, end)")
            if member.type_name == "boolean":
                out.line(f"out.append(_bools({self.t}, {ros!r}, buf, off, n))")
            elif size == 1:
                out.line("out.append(buf[off:off + n])")
            else:
                out.line(f"out.append(_swap{size}(buf, off, n))")
            out.line(f"off += n * {size}")
            return
        out.line(f"if n * {element} > end - off:")
        with out.indent():
            out.line(f"raise _bad_count({self.t}, {ros!r}, off, n, {element}, end)")
        out.line("for i in range(n):")
        with out.indent():
            self.element(member, f"'{ros}[%d]' % i")

    def element(self, member: Member, field: str) -> None:
        if member.type_name == "string":
            self.out.line(f"off = _string(buf, off, end, out, {self.t}, {field})")
            return
        statement = f"off = {self.idents[member.type_name]}(buf, off, end, out)"
        codegen.call_child(self.out, statement, "DecodeError", self.t, field)


def compile_encoders(
    structs: Mapping[str, StructDef], fingerprints: Mapping[str, bytes], names: Iterable[str]
) -> dict[str, LcmEncoder]:
    """The CDR -> LCM encoders of types `names` (none may contain itself; every nested type is in `structs`)."""
    helpers: dict[str, object] = {
        "DecodeError": DecodeError,
        "_truncated": codegen.truncated,
        "_run_error": _run_error,
        "_bools": _bools,
        "_length_error": _length_error,
        "_bad_count": codegen.bad_count,
        "_string": string_to_lcm,
        "_U32_LE": U32_LE,
        **{f"_swap{size}": codegen.swapped(size) for size in (2, 4, 8)},
    }
    bodies = codegen.compile_generated(
        structs, list(names), "C", _Generator, helpers, "<cdr -> lcm encoders>"
    )
    return {name: LcmEncoder(name, fingerprints[name], body,
                             functools.partial(learn_lcm_layout, structs, name, fingerprint=fingerprints[name]))
            for name, body in bodies.items()}  # fmt: skip
