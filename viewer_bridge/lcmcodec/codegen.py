"""What every generated codec shares: the source writer, reads and checks, size bounds and errors.

Three directions are generated or planned per struct: LCM <-> Python objects (`serde`), LCM -> CDR
(`cdr`), CDR -> LCM (`cdr_to_lcm`, one generator for LCM types and mapped ROS 2 types alike), and
JSON -> LCM (`json_to_lcm`) builds its plan from the same size bounds. Whatever they have in
common lives here once, under public names: the generated code calls these helpers by name (each
compiler puts them in its namespace), and the generators share one writer, one base class and the
emitters of what two directions write alike (a child's call, CDR scalar runs' starts).
"""

from __future__ import annotations

import functools
import math
import struct
import sys
import threading
from array import array
from collections.abc import Callable, Iterator, Mapping
from typing import Any, Protocol

import numpy as np

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.schema import (
    PRIMITIVE_FORMATS,
    STRING_MIN_SIZE,
    Member,
    StructDef,
    nested_closure,
)

Buffer = bytes | bytearray | memoryview
ReadLength = Callable[[Any, int], tuple[int]]  # a uint32 at an offset: big-endian (LCM) or little (CDR)
U32_BE: ReadLength = struct.Struct(">I").unpack_from
U32_LE: ReadLength = struct.Struct("<I").unpack_from
_SWAP_CODES = {2: "H", 4: "I", 8: "Q"}  # an array typecode of each size: byteswap only needs the size
_NUMPY_FROM = 256  # elements; below this Python's array module swaps faster than numpy's call overhead


# --- errors -------------------------------------------------------------------------------------


def truncated(type_name: str, field: str, offset: int, need: int, end: int) -> DecodeError:
    """`need` bytes were wanted at `offset`, and the buffer ends at `end`."""
    return DecodeError(
        type_name, field, offset, f"truncated: needs {need} bytes, {max(end - offset, 0)} remain"
    )


def bad_count(type_name: str, field: str, offset: int, count: int, size: int, end: int) -> DecodeError:
    """A negative count, or one whose elements of at least `size` bytes cannot fit before `end`."""
    if count < 0:
        return DecodeError(type_name, field, offset, f"negative count {count}")
    return DecodeError(
        type_name,
        field,
        offset,
        f"count {count} needs at least {count * size} bytes, {max(end - offset, 0)} remain",
    )


# --- strings: a uint32 length that counts a closing NUL, the UTF-8 bytes, the NUL ---------------


def string_error(
    type_name: str, field: str, buf: Buffer, offset: int, end: int, read_length: ReadLength = U32_BE
) -> DecodeError:
    """The precise error for the malformed string at `offset` (the slow path: only once something is wrong)."""
    if offset + 4 > end:
        return truncated(type_name, field, offset, 4, end)
    (length,) = read_length(buf, offset)
    start = offset + 4
    if length == 0:
        return DecodeError(type_name, field, offset, "string length 0 leaves no room for its NUL")
    if start + length > end:
        return truncated(type_name, field, start, length, end)
    if buf[start + length - 1] != 0:
        return DecodeError(type_name, field, start + length - 1, "string is not NUL-terminated")
    try:
        str(buf[start : start + length - 1], "utf-8")
    except UnicodeDecodeError as error:
        return DecodeError(type_name, field, start + error.start, "invalid UTF-8")
    return DecodeError(type_name, field, offset, "malformed string")


def string_stop(
    buf: Any, off: int, end: int, type_name: str, field: str, read_length: ReadLength = U32_BE
) -> int:
    """Where the string at `off` ends (after its NUL), once it is checked whole: length, NUL, UTF-8.
    LCM and CDR write a string alike but for the byte order of its length (`read_length`)."""
    if off + 4 > end:
        raise string_error(type_name, field, buf, off, end, read_length)
    (length,) = read_length(buf, off)
    stop = off + 4 + length
    if length == 0 or stop > end or buf[stop - 1] != 0:
        raise string_error(type_name, field, buf, off, end, read_length)
    try:
        str(buf[off + 4 : stop - 1], "utf-8")
    except UnicodeDecodeError:
        raise string_error(type_name, field, buf, off, end, read_length) from None
    return stop


# --- arrays -------------------------------------------------------------------------------------


class _Scratch(threading.local):
    """Where one thread's long arrays are byte-swapped: reused message after message. A fresh
    800 kB array per message costs more in page faults than the swap itself (and two alive at
    once, the swapped copy and the joined output, made glibc give the memory back and fault it in
    again each time: 3 ms for `double[100000]` where a memcpy takes 0.03). The swapped elements
    never leave the codec: they are copied into the message's output by its join, so the next
    message may write over them. Within one message each swap takes the next free bytes; a
    thread's scratch stays as large as the most one of its messages has swapped."""

    def __init__(self) -> None:
        self.buffer = np.empty(0, np.uint8)
        self.used = 0

    def take(self, nbytes: int) -> np.ndarray[Any, np.dtype[np.uint8]]:
        """`nbytes` bytes no earlier swap of this message holds, 8-aligned."""
        start = -(-self.used // 8) * 8
        if start + nbytes > len(self.buffer):  # a new buffer: the old one lives on in this message's views
            self.buffer = np.empty(max(start + nbytes, 2 * len(self.buffer)), np.uint8)
            start = 0
        self.used = start + nbytes
        return self.buffer[start : start + nbytes]


_SCRATCH = _Scratch()


def new_message() -> None:
    """Called before a message's generated code runs: the previous message's swapped arrays (in
    this thread) are in its output already, so their scratch bytes are free again."""
    _SCRATCH.used = 0


def swapped(size: int) -> Callable[[bytes | memoryview, int, int], object]:
    """A function returning `count` elements of `size` bytes at `offset`, each byte-reversed
    (big-endian LCM <-> little-endian CDR, on a little-endian host). A long array's are in this
    thread's scratch, valid until the next `new_message`."""
    code = _SWAP_CODES[size]
    native, reversed_ = np.dtype(f"<u{size}"), np.dtype(f">u{size}")

    def swap(buf: bytes | memoryview, offset: int, count: int) -> object:
        if count < _NUMPY_FROM:
            items = array(code)
            items.frombytes(buf[offset : offset + count * size])
            items.byteswap()
            return items
        # A byte-order cast into the scratch: one pass, aligned or not, and no fresh memory.
        elements = _SCRATCH.take(count * size).view(native)
        np.copyto(elements, np.frombuffer(buf, reversed_, count, offset))
        return elements

    return swap


# --- size bounds --------------------------------------------------------------------------------


def min_sizes(structs: Mapping[str, StructDef]) -> dict[str, int]:
    """Smallest LCM body of each type (every variable array empty, every string empty): the bound
    that rejects impossible counts before anything is allocated. A type nested in itself counts 0
    at the inner level (its variable array may be empty)."""
    sizes: dict[str, int] = {}

    def size_of(definition: StructDef, parents: tuple[str, ...]) -> int:
        if definition.full_name in sizes:
            return sizes[definition.full_name]
        total = 0
        inside = parents + (definition.full_name,)
        for member in definition.members:
            if any(dim.is_variable for dim in member.dims):
                continue
            count = math.prod(dim.count for dim in member.dims)
            nested = member.type_name in structs and member.type_name not in inside
            element = size_of(structs[member.type_name], inside) if nested else _leaf_min_size(member)
            total += count * element
        sizes[definition.full_name] = total
        return total

    for definition in structs.values():
        size_of(definition, ())
    return sizes


def _leaf_min_size(member: Member) -> int:
    """The fewest bytes of a primitive or string element; 0 for a type nested in itself."""
    if member.type_name == "string":
        return STRING_MIN_SIZE
    if member.type_name in PRIMITIVE_FORMATS:
        return PRIMITIVE_FORMATS[member.type_name][1]
    return 0


def element_min_size(member: Member, sizes: Mapping[str, int]) -> int:
    """The fewest bytes one element of `member` takes (`sizes`: each struct's, from `min_sizes`)."""
    if member.type_name == "string" or member.type_name in PRIMITIVE_FORMATS:
        return _leaf_min_size(member)
    return sizes[member.type_name]


def closure_min_sizes(structs: Mapping[str, StructDef], names: list[str]) -> tuple[list[str], dict[str, int]]:
    """`names` and every type they nest (in `nested_closure`'s order), and each one's `min_sizes`."""
    needed = nested_closure(structs, names)
    return needed, min_sizes({name: structs[name] for name in needed})


# --- writing and compiling source ---------------------------------------------------------------


class SourceWriter:
    """Lines of Python source, indented by `with writer.indent():`."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.depth = 0

    def line(self, text: str) -> None:
        self.lines.append("    " * self.depth + text)

    def indent(self) -> _IndentScope:
        return _IndentScope(self)

    def source(self) -> str:
        return "\n".join(self.lines) + "\n"


class _IndentScope:
    def __init__(self, writer: SourceWriter) -> None:
        self.writer = writer

    def __enter__(self) -> None:
        self.writer.depth += 1

    def __exit__(self, *exc: object) -> None:
        self.writer.depth -= 1


def call_child(out: SourceWriter, statement: str, error_class: str, type_literal: str, field: str) -> None:
    """Write `statement` (a child struct's codec) so that its error is re-homed under the type
    `type_literal` (a Python literal) and `field` (an expression)."""
    out.line("try:")
    with out.indent():
        out.line(statement)
    out.line(f"except {error_class} as error:")
    with out.indent():
        out.line(f"raise error.within({type_literal}, {field}) from None")


def aligned_starts(phase: int, sizes: list[int]) -> list[int]:
    """Where consecutive CDR primitives of `sizes` bytes start, counted from the first one's position,
    when that position is `phase` modulo 8 (each is aligned to its size): a generated run of CDR
    scalars is read with one `struct` per phase."""
    starts, position = [], phase
    for size in sizes:
        position += -position & (size - 1)
        starts.append(position - phase)
        position += size
    return starts


def scalar_runs(definition: StructDef) -> Iterator[tuple[bool, list[tuple[int, Member]]]]:
    """The members in order, as runs of fixed-size scalars (True: read or written with one
    `struct` call) and each other member alone (False), with their indices."""
    run: list[tuple[int, Member]] = []
    for index, member in enumerate(definition.members):
        if member.type_name in PRIMITIVE_FORMATS and not member.dims:
            run.append((index, member))
            continue
        if run:
            yield True, run
            run = []
        yield False, [(index, member)]
    if run:
        yield True, run


# --- writing CDR: what the LCM -> CDR transcoders and the value writers emit alike ---------------

CDR_LE = b"\x00\x01\x00\x00"  # the encapsulation header: little-endian plain CDR
COUNT_AFTER_PAD = [struct.Struct(f"<{pad}xI") for pad in range(4)]  # a uint32 after `pad` zero bytes


def cdr_packers(codes: list[tuple[str, int]]) -> tuple[list[struct.Struct], list[int]]:
    """A run of CDR scalars (little-endian `struct` codes with their sizes) as one packer per
    position modulo 8, each with the padding that aligns every scalar to its size, and the bytes
    each packer writes. A run written at position `pos` is `packers[pos & 7]`."""
    packers = []
    for phase in range(8):
        fmt, position = "<", phase
        for code, size in codes:
            pad = -position & (size - 1)
            fmt += "x" * pad + code
            position += pad + size
        packers.append(struct.Struct(fmt))
    return packers, [packer.size for packer in packers]


@functools.lru_cache(maxsize=4096)
def cdr_glue(phase: int, count: int, size: int, sequence: bool) -> tuple[bytes, int]:
    """The bytes before an array of `count` elements of `size` bytes at a position of `phase`
    modulo 8 (padding, and a sequence's uint32 count), and how far the position moves in all."""
    glue = b""
    position = phase
    if sequence:
        pad = -position & 3
        glue = COUNT_AFTER_PAD[pad].pack(count)
        position += pad + 4
    if count:  # an empty array is not aligned (as rosbags and Fast CDR write it)
        pad = -position & (size - 1)
        glue += bytes(pad)
        position += pad + count * size
    return glue, position - phase


class StructWriter:
    """Base of a generator that writes one function per struct, named by `idents`, for
    `compile_generated`: what each generator needs to know, and how a member is found."""

    def __init__(self, struct_: StructDef, idents: Mapping[str, str], sizes: Mapping[str, int],
                 out: SourceWriter, formats: dict[str, object]) -> None:  # fmt: skip
        self.struct = struct_
        self.idents = idents
        self.min_sizes = sizes
        self.out = out
        self.formats = formats  # names the generated code uses -> the objects behind them
        self.ident = idents[struct_.full_name]
        self.t = repr(struct_.full_name)
        # By name, once: a struct of 10,000 sized arrays looks up 10,000 length fields.
        self._indices = {member.name: index for index, member in enumerate(struct_.members)}

    def write(self) -> None:
        raise NotImplementedError

    def index_of(self, name: str) -> int:
        """The index of member `name` (a length field): the generated code holds it as `v<index>`."""
        return self._indices[name]


class _Writes(Protocol):
    def write(self) -> None: ...


# What writes one struct's function: a `StructWriter` class, or anything made the same way.
MakeWriter = Callable[
    [StructDef, Mapping[str, str], Mapping[str, int], SourceWriter, dict[str, object]], _Writes
]


def compile_generated(
    structs: Mapping[str, StructDef], names: list[str], prefix: str, generator: MakeWriter,
    helpers: Mapping[str, object], filename: str,
) -> dict[str, Callable[..., Any]]:  # fmt: skip
    """Generate one function per type of `names` and of every type they nest (named `prefix` and a
    number), with `generator`'s `write`, compile them together with `helpers` in their namespace,
    and return those of `names`."""
    needed, sizes = closure_min_sizes(structs, names)
    idents = {name: f"{prefix}{index}" for index, name in enumerate(needed)}
    out = SourceWriter()
    formats: dict[str, object] = {}
    for name in needed:
        generator(structs[name], idents, sizes, out, formats).write()
    namespace: dict[str, Any] = {**helpers, **formats}
    exec(compile(out.source(), filename, "exec"), namespace)  # noqa: S102
    return {name: namespace[idents[name]] for name in names}


assert sys.byteorder == "little", "the swaps assume a little-endian host"  # noqa: S101
