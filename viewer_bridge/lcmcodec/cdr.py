"""LCM bytes -> ROS 2 CDR bytes, with code generated per type and compiled once.

The generated function of a struct reads LCM's big-endian wire format and appends the CDR of the
mapped ROS 2 message (docs/PROTOCOLS.md, "Any LCM type") to a list of byte chunks, keeping the
CDR position for alignment. Nothing is built per field: a run of scalars is one `struct` unpack
and one pack (the pack's padding chosen by the position modulo 8), a primitive array is one
byte-swapped copy (Python's `array` for short ones, numpy for long ones), a byte array a slice;
the chunks are joined once at the end.

CDR (XCDR1, little-endian, as ROS 2 writes it): a 4-byte encapsulation header, then each
primitive aligned to its own size counted from the end of the header; a sequence is a uint32
count then its elements (aligned only when there is at least one); a string a uint32 length
including a NUL, the UTF-8 bytes and the NUL; a nested message inline; an empty message the one
`uint8` ROS 2 gives it.

Bad input raises `DecodeError` naming the type, the field path and the byte offset: a wrong
fingerprint, too few or too many bytes, a negative length, a count whose elements could not fit
in the bytes that remain (checked before anything is allocated), a string without its NUL or not
UTF-8. The reverse direction (CDR -> LCM) is `cdr_to_lcm`, compiled by the same `codegen.compile_generated`.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Iterator, Mapping
from functools import lru_cache, partial
from typing import Any

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.codegen import (
    COUNT_AFTER_PAD,
    Buffer,
    StructWriter,
    bad_count,
    call_child,
    cdr_glue,
    cdr_packers,
    compile_generated,
    element_min_size,
    new_message,
    string_stop,
    swapped,
    truncated,
)
from viewer_bridge.lcmcodec.layout import CDR_HEADER, Layout, LayoutKeeper, learn_lcm_layout
from viewer_bridge.lcmcodec.schema import PRIMITIVE_FORMATS, Member, StructDef

Chunks = list[Any]  # what b"".join takes: bytes, memoryviews, arrays, numpy arrays
# A float32 scalar moves as its raw bits ("I"): through a Python float a signalling NaN would turn quiet.
_LE_CODES = {"int8_t": "b", "int16_t": "h", "int32_t": "i", "int64_t": "q", "float": "I", "double": "d",
             "boolean": "?", "byte": "B"}  # fmt: skip
_BE_CODES = {name: "I" if name == "float" else code for name, (code, _) in PRIMITIVE_FORMATS.items()}
_BOOLS = bytes([0] + [1] * 255)  # LCM reads any non-zero byte as true; CDR wants 0 or 1
_ZEROS = [bytes(n) for n in range(8)]
_FIELD_FINGERPRINT = "<fingerprint>"
_VIEW_FROM = 4096  # bytes


class CdrTranscoder(LayoutKeeper):
    """The compiled LCM -> CDR path of one type.

    After a message has passed the generated code, its layout (`layout`) is kept by size: a
    message of the same size and shape (fingerprint, length fields, string lengths) is one call
    of the compiled mover, which compares those values and moves the bytes (without a compiler,
    the same in Python). Anything else takes the generated code, which finds and names what is
    wrong."""

    def __init__(self, type_name: str, packed_fingerprint: bytes,
                 body: Callable[[bytes | memoryview, int, int, Chunks, int], tuple[int, int]],
                 learn: Callable[[bytes], Layout | None] | None = None) -> None:  # fmt: skip
        super().__init__(learn)
        self.type_name = type_name
        self.packed_fingerprint = packed_fingerprint
        self._body = body

    # A whole LCM message (fingerprint first) as CDR with its encapsulation header. `convert`
    # itself, not a method calling it: the fast path is a few calls, one more shows.
    transcode = LayoutKeeper.convert

    def _convert(self, data: Buffer) -> bytes:
        """The generated code's way: every check, every error named."""
        # Small bytes are read as they are (slicing bytes is cheapest); anything else through a
        # flat byte view, so that a large byte array is copied once, into the result, not twice.
        buf = data if type(data) is bytes and len(data) < _VIEW_FROM else memoryview(data).cast("B")
        end = len(buf)
        if buf[:8] != self.packed_fingerprint:
            found = bytes(buf[:8]).hex()
            raise DecodeError(
                self.type_name, _FIELD_FINGERPRINT, 0,
                f"fingerprint {found} is not {self.packed_fingerprint.hex()}" if end >= 8 else f"truncated: {end} bytes",
            )  # fmt: skip
        out: Chunks = [CDR_HEADER]
        new_message()  # the previous message's swapped arrays were copied into its CDR
        offset, _ = self._body(buf, 8, end, out, 0)
        if offset != end:
            raise DecodeError(self.type_name, "<end>", offset, f"{end - offset} trailing bytes")
        return b"".join(out)


def _string(
    buf: bytes | memoryview, off: int, end: int, out: Chunks, pos: int, type_name: str, field: str
) -> tuple[int, int]:
    """One string: LCM's big-endian length to CDR's little-endian one (both count the NUL)."""
    stop = string_stop(buf, off, end, type_name, field)
    pad = -pos & 3
    out.append(COUNT_AFTER_PAD[pad].pack(stop - off - 4))
    out.append(buf[off + 4 : stop])
    return stop, pos + pad + stop - off


@lru_cache(maxsize=1024)
def _run_glue(
    phase: int, count: int, size: int, many: int
) -> tuple[tuple[bytes, ...], tuple[slice, ...], int]:
    """For `many` sequences of `count` elements of `size` bytes, one after the other from a
    position of `phase` modulo 8: the bytes before each, each one's slice of the swapped
    elements, and how far the position moves in all."""
    glues: list[bytes] = []
    position = phase
    for _ in range(many):
        glue, step = cdr_glue(position & 7, count, size, True)
        glues.append(glue)
        position += step
    cuts = tuple(slice(i * count, (i + 1) * count) for i in range(many))
    return tuple(glues), cuts, position - phase


def _shared_count_error(
    type_name: str, fields: tuple[str, ...], off: int, count: int, size: int, end: int
) -> DecodeError:
    """The error for sequences sharing one length: the first whose elements do not fit."""
    for index, field in enumerate(fields):
        start = off + index * count * size
        if count < 0 or start + count * size > end:
            return bad_count(type_name, field, start, count, size, end)
    raise AssertionError("no sequence overflows")  # the caller checked that one does


def _check_count(type_name: str, field: str, off: int, end: int, shape: tuple[int, ...], element: int) -> int:
    """The element count of an array of `shape`, refused when negative or more than the bytes left."""
    count = 1
    for size in shape:
        if size < 0:
            raise bad_count(type_name, field, off, size, element, end)
        count *= size
    if count * element > end - off:
        raise bad_count(type_name, field, off, count, element, end)
    return count


class _Generator(StructWriter):
    """Writes the LCM -> CDR function of one struct."""

    def write(self) -> None:
        out = self.out
        out.line(f"def {self.ident}(buf, off, end, out, pos):")
        with out.indent():
            if not self.struct.members:  # ROS 2 gives an empty message one uint8
                out.line("out.append(b'\\0')")
                out.line("pos += 1")
            for kind, group in self.groups():
                if kind == "scalars":
                    self.scalars(group)
                elif kind == "arrays":
                    self.swapped_arrays(group)
                else:
                    self.member(group[0])
            out.line("return off, pos")

    def groups(self) -> Iterator[tuple[str, list[tuple[int, Member]]]]:
        """Runs of scalars, runs of primitive arrays of one element size (swapped in one go), and
        each other member alone."""
        kind = ""
        run: list[tuple[int, Member]] = []
        for index, member in enumerate(self.struct.members):
            if member.type_name in PRIMITIVE_FORMATS and not member.dims:
                this = "scalars"
            elif member.type_name in PRIMITIVE_FORMATS and PRIMITIVE_FORMATS[member.type_name][1] > 1:
                this = f"arrays{PRIMITIVE_FORMATS[member.type_name][1]}"
            else:
                this = "other"
            if run and (this != kind or this == "other"):
                yield kind.rstrip("248"), run
                run = []
            kind = this
            run.append((index, member))
        if run:
            yield kind.rstrip("248"), run

    def swapped_arrays(self, run: list[tuple[int, Member]]) -> None:
        """Consecutive arrays of one element size: lengths checked, one byte swap, then per array
        its count (a sequence's) and padding, and its slice of the swapped elements."""
        out = self.out
        size = PRIMITIVE_FORMATS[run[0][1].type_name][1]
        lengths = {member.dims for _, member in run}
        if len(run) > 1 and len(lengths) == 1 and [dim.is_variable for dim in run[0][1].dims] == [True]:
            self.same_length_arrays(run, size)
            return
        counts = []
        for number, (_, member) in enumerate(run):
            count = f"n{number}"
            counts.append(count)
            before = " + ".join(counts[:-1]) or "0"
            variable = [dim for dim in member.dims if dim.is_variable]
            if len(member.dims) == 1 and variable:
                out.line(f"{count} = v{self.index_of(variable[0].size)}")
                out.line(f"if {count} < 0 or ({before} + {count}) * {size} > end - off:")
                with out.indent():
                    out.line(f"raise _bad_count({self.t}, {member.name!r}, off + ({before}) * {size}, "
                             f"{count}, {size}, end)")  # fmt: skip
            else:
                out.line(
                    f"{count} = _check_count({self.t}, {member.name!r}, off + ({before}) * {size}, end, "
                    f"({self.shape(member)},), {size})"
                )
        total = " + ".join(counts)
        out.line(f"if ({total}) * {size} > end - off:")
        with out.indent():
            out.line(f"raise _bad_count({self.t}, {run[-1][1].name!r}, off, {total}, {size}, end)")
        out.line(f"swapped = _swap{size}(buf, off, {total})")
        if len(run) > 1:
            out.line("swapped = _view(swapped)")
        start = "0"
        for number, (_, member) in enumerate(run):
            count = counts[number]
            sequence = not (len(member.dims) == 1 and not member.dims[0].is_variable)
            # What goes before the elements (padding, a sequence's count) and the position after
            # them depend on the position modulo 8 and the count only: cached per pair.
            out.line(f"glue, step = _glue(pos & 7, {count}, {size}, {sequence})")
            out.line("out.append(glue)")
            out.line(
                f"out.append(swapped[{start}:{start} + {count}])" if len(run) > 1 else "out.append(swapped)"
            )
            out.line("pos += step")
            start = f"{start} + {count}" if start != "0" else count
        out.line(f"off += ({total}) * {size}")

    def same_length_arrays(self, run: list[tuple[int, Member]], size: int) -> None:
        """Sequences that share one length member (a robot's positions, velocities, torques ...):
        one check, one swap, and the counts, padding and cuts cached per (position % 8, length)."""
        out, many = self.out, len(run)
        names = tuple(member.name for _, member in run)
        out.line(f"n = v{self.index_of(run[0][1].dims[0].size)}")
        out.line(f"if n < 0 or {many * size} * n > end - off:")
        with out.indent():
            out.line(f"raise _shared_count_error({self.t}, {names!r}, off, n, {size}, end)")
        out.line(f"swapped = _view(_swap{size}(buf, off, {many} * n))")
        out.line(f"glues, cuts, step = _run_glue(pos & 7, n, {size}, {many})")
        pieces = ", ".join(f"glues[{i}], swapped[cuts[{i}]]" for i in range(many))
        out.line(f"out += ({pieces})")
        out.line("pos += step")
        out.line(f"off += {many * size} * n")

    def shape(self, member: Member) -> str:
        return ", ".join(
            f"v{self.index_of(dim.size)}" if dim.is_variable else str(dim.count) for dim in member.dims
        )

    def scalars(self, run: list[tuple[int, Member]]) -> None:
        """Fixed scalars: one big-endian unpack, one little-endian pack padded for `pos % 8`."""
        out = self.out
        sizes = [PRIMITIVE_FORMATS[m.type_name][1] for _, m in run]
        total = sum(sizes)
        name = f"{self.ident}_S{len(self.formats)}"
        self.formats[name] = struct.Struct(">" + "".join(_BE_CODES[m.type_name] for _, m in run))
        codes = [(_LE_CODES[member.type_name], size) for (_, member), size in zip(run, sizes, strict=True)]
        self.formats[name + "_LE"], self.formats[name + "_N"] = cdr_packers(codes)
        out.line(f"if off + {total} > end:")
        with out.indent():
            position = 0
            for (_, member), size in zip(run, sizes, strict=True):
                out.line(f"if off + {position + size} > end:")
                with out.indent():
                    out.line(f"raise _truncated({self.t}, {member.name!r}, off + {position}, {size}, end)")
                position += size
        values = ", ".join(f"v{index}" for index, _ in run)
        out.line(f"{values}{',' if len(run) == 1 else ''} = {name}.unpack_from(buf, off)")
        out.line(f"off += {total}")
        out.line("k = pos & 7")
        out.line(f"out.append({name}_LE[k].pack({values}))")
        out.line(f"pos += {name}_N[k]")

    def member(self, indexed: tuple[int, Member]) -> None:
        _, member = indexed
        if not member.dims:
            self.element(member, repr(member.name))
            return
        out = self.out
        shape = self.shape(member)
        fixed = len(member.dims) == 1 and not member.dims[0].is_variable
        element = max(element_min_size(member, self.min_sizes), 1)
        out.line(f"n = _check_count({self.t}, {member.name!r}, off, end, ({shape},), {element})")
        if not fixed:
            out.line("p = -pos & 3")
            out.line("out.append(COUNT_AFTER_PAD[p].pack(n))")
            out.line("pos += p + 4")
        if member.type_name in ("byte", "int8_t"):
            out.line("out.append(buf[off:off + n])")
            out.line("off += n")
            out.line("pos += n")
        elif member.type_name == "boolean":
            out.line("out.append(bytes(buf[off:off + n]).translate(_BOOLS))")
            out.line("off += n")
            out.line("pos += n")
        else:
            out.line("for i in range(n):")
            with out.indent():
                self.element(member, f"'{member.name}[%d]' % i")

    def element(self, member: Member, field: str) -> None:
        out = self.out
        if member.type_name == "string":
            out.line(f"off, pos = _string(buf, off, end, out, pos, {self.t}, {field})")
            return
        statement = f"off, pos = {self.idents[member.type_name]}(buf, off, end, out, pos)"
        call_child(out, statement, "DecodeError", self.t, field)


def compile_transcoders(
    structs: Mapping[str, StructDef], fingerprints: Mapping[str, bytes], names: Iterable[str],
    keep_layouts: bool = True,
) -> dict[str, CdrTranscoder]:  # fmt: skip
    """The transcoders of types `names` (none may contain itself; every nested type is in `structs`).
    Each keeps the layouts of the messages it has converted unless `keep_layouts` is False: then
    every message takes the generated code (as the first of each shape does)."""
    helpers: dict[str, object] = {
        "DecodeError": DecodeError,
        "_truncated": truncated,
        "_check_count": _check_count,
        "_string": _string,
        "COUNT_AFTER_PAD": COUNT_AFTER_PAD,
        "_ZEROS": _ZEROS,
        "_bad_count": bad_count,
        "_glue": cdr_glue,
        "_run_glue": _run_glue,
        "_shared_count_error": _shared_count_error,
        "_view": memoryview,
        "_BOOLS": _BOOLS,
        **{f"_swap{size}": swapped(size) for size in (2, 4, 8)},
    }
    bodies = compile_generated(structs, list(names), "T", _Generator, helpers, "<lcm -> cdr transcoders>")
    return {name: CdrTranscoder(name, fingerprints[name], body,
                                partial(learn_lcm_layout, structs, name) if keep_layouts else None)
            for name, body in bodies.items()}  # fmt: skip
