"""Kept layouts: the fast path of every LCM <-> CDR conversion (`cdr`, `cdr_to_lcm`, `ros_cdr`).

A stream of one type mostly repeats its shape: a robot's status has the same joint count, a
`JointState` the same joint names, so the same array lengths and string lengths message after
message; only numbers change. Once a message has passed the generated code (every check, every
error named), its layout is found here by walking the type over its bytes: where each value sits
on the input side and on the output side, and the values that fix the shape (header or
fingerprint, length fields, sequence counts, each string's length and NUL) with what they were.
A later message of the same size whose shape values are the same has the same layout (each
position follows from the ones before it), so it is converted without the generated code.

One walk, in the order both wire formats share (LCM and CDR both write fields in declaration
order; CDR adds alignment, sequence counts and its header), gives a list of values, each with its
input and output offset, size and `struct` code. It compiles to a *move program* for the compiled
mover (`_mover.c`, a C extension `hatch_build.py` builds with the interpreter's own compiler
settings): the output's template (its prefix, CDR's sequence counts that LCM does not carry, zero
padding), the input bytes that must equal the kept shape values (comparing the raw bytes is
comparing the values: both are read the same way), the checks below, and runs of values copied
with their bytes reversed (LCM is big-endian, CDR here little-endian), widened into the
template's zeros (a CDR unsigned integer as LCM's next signed one). The C mover checks the
program against its sizes on every call and the message's size against the program: no input
reads or writes out of bounds. Why C: `lcmt_iiwa_status` -> CDR took 1.2-1.5 us through the
Python movers below, and one bare `struct` unpack and pack of its 51 values alone takes 0.85 us,
so Python could not come near 20x lcm-gen + rclpy (15-19 us); through its program it takes
0.27-0.45 us (35-37x; the move itself 0.14 us, a third of it the new `bytes`), CDR ->
`lcmt_iiwa_command` 0.21 us against 0.82 us (38x), one run each of `bench/lcm_generic.py` on the
2-core machine, quiet then.

Built without a compiler (the build warned), the extension is missing and `COMPILED_MOVER` is
False; the walk then compiles to one of two Python movers, the same bytes:
- one `struct` that reads every value and one that writes them (`prefix + write(*values)`), when
  the output holds nothing but those values, zero padding and a prefix (CDR -> LCM; LCM -> CDR
  without sequences) and there are at most `STRUCT_VALUES` values;
- otherwise a gather of bytes, `(message + tail)[gather]` with numpy, where `tail` holds the
  constants (a CDR sequence's count is one). A gather makes no Python object per number, and
  checks no value: a layout whose input values need checking (CDR bools, a uint64 that LCM's
  int64 cannot hold) has no gather.

Checks on the fast path: the shape values equal the kept ones; each CDR bool is 0 or 1; every
string is UTF-8 (as `str(text, "utf-8")` says: the C mover checks ASCII itself and hands anything
else to Python's decoder; the Python movers decode all strings joined by NULs, so a character cut
at the end of one cannot pass as whole with the next); a uint64 is below 2^63 (its top byte below
0x80; the "q" pack raises). LCM reads any bool byte but 0 as true and CDR writes 1: an LCM bool
becomes `!= 0`. Anything else takes the generated code, which finds and names it: a truncated
message has another size (a layout is kept by size), a count claiming 2^31 elements is a shape
value that differs, so both meet the generated code's typed `DecodeError`.

Bounds: messages above `LAYOUT_BYTES` have no layout (the generated code copies each array once,
a layout twice); a program takes at most `PROGRAM_BYTES` (a record or two of 20-28 bytes per
piece, an array being one piece and a string three: many short strings take more, and then the
Python movers' bounds apply). The struct pair takes at most `STRUCT_VALUES` values (beyond it, the
generated code's one byte swap per array is faster), a gather at most `GATHER_BYTES` output bytes
(its index is 8 bytes per byte). Each converter keeps at most `LAYOUTS` sizes per type and direction.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Mapping
from functools import partial
from operator import itemgetter
from types import MappingProxyType
from typing import Any, Final, NamedTuple, final

import numpy as np

from viewer_bridge.errors import NoLayout
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.lcmcodec.from_ros import RosField, RosStruct
from viewer_bridge.lcmcodec.schema import PRIMITIVE_FORMATS, Member, StructDef

try:
    from viewer_bridge.lcmcodec._mover import move as _move

    COMPILED_MOVER = True  # programs are built (the tests turn it off to run the Python movers)
except ImportError:  # built without a compiler (hatch_build.py warned): the Python movers
    COMPILED_MOVER = False

    def _move(program: Buffer, data: Buffer, /) -> bytes | None:  # no program is built: never called
        return None


try:  # one call for a converter's kept program (an extension built before it was added has none)
    from viewer_bridge.lcmcodec._mover import move_kept as _move_kept
except ImportError:
    _move_kept = None  # type: ignore[assignment]


LAYOUTS: Final = 16  # sizes kept per type (a robot sends one or two)
LAYOUT_BYTES: Final = 16384
STRUCT_VALUES: Final = 256
GATHER_BYTES: Final = 4096
PROGRAM_BYTES: Final = 65536  # a record or two per array or string part: many short strings take more
CDR_HEADER: Final = b"\x00\x01\x00\x00"  # little-endian CDR, no options
_FINGERPRINT = 8
_CDR_LE = b"\x00\x01"
# How an LCM primitive is read and written, the same code on both sides: a float32 as its raw bits
# (through a Python float a signalling NaN would turn quiet); a bool as a byte, checked to be 0 or 1
# when CDR (an LCM bool is read by "?": any byte but 0 is true).
_LCM_CODES = {**{name: code for name, (code, _) in PRIMITIVE_FORMATS.items()}, "float": "I", "boolean": "B"}
# ROS 2 primitive -> (CDR size, little-endian code, LCM's big-endian code): `cdr_to_lcm.WIRE`.
Wire = Mapping[str, tuple[int, str, str]]
_frombuffer, _BYTE = np.frombuffer, np.dtype(np.uint8)  # looked up once: the fast path is a few calls


class PythonLayout(NamedTuple):  # a tuple: unpacked at once on the fast path
    """How the messages of one size and shape convert: a message whose `key` values (of `read`'s
    tuple; the whole tuple when `key` is None) are `expected` has this layout, and is valid when
    its `bools` are 0 or 1 and its `texts` UTF-8. Its output is `prefix + write(*values)`, or,
    when `write` is None, `(message + tail)[gather]` with the bytes at `normalize` made 0 or 1."""

    read: Callable[[Buffer], tuple[Any, ...]]
    key: Callable[[tuple[Any, ...]], tuple[Any, ...]] | None
    expected: tuple[Any, ...]
    bools: Callable[[tuple[Any, ...]], tuple[int, ...]] | None  # CDR bools: each must be 0 or 1
    texts: Callable[[tuple[Any, ...]], tuple[bytes, ...]] | None  # each string's bytes: must be UTF-8
    prefix: bytes
    write: Callable[..., bytes] | None
    tail: bytes
    gather: np.ndarray[Any, np.dtype[np.intp]] | None  # each output byte's index in message + tail
    normalize: np.ndarray[Any, np.dtype[np.intp]] | None  # the output positions of LCM bools


@final  # final: `type(layout) is MoveProgram` tells mypy the other case is a PythonLayout
class MoveProgram(bytes):
    """A layout as a program of the compiled mover (`_mover.c` says what its bytes hold)."""


Layout = PythonLayout | MoveProgram
_UNSEEN: Final[Any] = object()
# `_mover.c`'s records: a check (kind, at, count, step, arg), its kinds; a run (in_at, out_at,
# count, in_step, out_step, width, flags), its flags.
_Check = tuple[int, int, int, int, int]
_EQUAL, _AT_MOST, _UTF8 = 0, 1, 2
_Run = tuple[int, int, int, int, int, int, int]
_SWAP, _NONZERO = 1, 2


class LayoutKeeper:
    """A converter that keeps the layouts of the messages its generated code (`_convert`) has
    passed, by size (`LAYOUTS` at most, a size whose message has no layout remembered as None),
    and converts a message of a kept layout without it."""

    def __init__(self, learn: Callable[[bytes], Layout | None] | None) -> None:
        self._learn = learn
        self._layouts: dict[int, Layout | None] = {}

    def _convert(self, data: Buffer) -> bytes:
        """The generated code's way: every check, every error named."""
        raise NotImplementedError

    @property
    def layouts(self) -> Mapping[int, Layout | None]:
        """The kept layouts by message size (None: that size had none), read only."""
        return MappingProxyType(self._layouts)

    def generated(self, data: Buffer) -> bytes:
        """`data` converted by the generated code alone, never a kept layout: what `convert`'s
        bytes and errors must agree with."""
        return self._convert(data)

    def kept(self) -> Callable[[bytes], bytes | None] | None:
        """A function that converts a message through its kept compiled program in one C call,
        or says None when it has none that fits (then `convert` does it: the generated code, and
        learning its layout); None while no compiled program is kept, or none can be."""
        if _move_kept is None or not any(type(layout) is MoveProgram for layout in self._layouts.values()):
            return None
        return partial(_move_kept, self._layouts)

    def convert(self, data: Buffer) -> bytes:
        """`data` converted: through its kept layout when it has one, else the generated code."""
        # inline: a call less
        if type(data) is bytes and (layout := self._layouts.get(len(data))) is not None:
            moved = _move(layout, data) if type(layout) is MoveProgram else _python_move(layout, data)
            if moved is not None:
                return moved
        out = self._convert(data)
        if self._learn is not None and type(data) is bytes:
            kept = self._layouts.get(len(data), _UNSEEN)
            # A size seen before is learnt again (its stream's shape changed), unless it had no layout.
            if kept is not None and (kept is not _UNSEEN or len(self._layouts) < LAYOUTS):
                self._layouts[len(data)] = self._learn(data)
        return out


def _python_move(layout: PythonLayout, data: bytes) -> bytes | None:
    """`data` converted by a Python layout, or None when it does not fit (the generated code says why)."""
    read, key, expected, bools, texts, prefix, write, tail, gather, normalize = layout
    values = read(data)
    if (values if key is None else key(values)) != expected or (bools is not None and max(bools(values)) > 1):
        return None
    try:
        if texts is not None:  # joined by NULs: a character cut at the end of one is no whole one
            str(b"\0".join(texts(values)), "utf-8")
        if write is not None:
            return prefix + write(*values)
    except (UnicodeDecodeError, struct.error):  # or a uint64 from 2^63
        return None
    moved = _frombuffer(data + tail, _BYTE)[gather]
    if normalize is not None:  # LCM reads any byte but 0 as true, CDR writes 1
        moved[normalize] = moved[normalize] != 0
    out: bytes = moved.tobytes()
    return out


def _items(indices: list[int]) -> Callable[[tuple[Any, ...]], tuple[Any, ...]] | None:
    """The values at `indices` as a tuple, even for one (`itemgetter` gives that one alone); None for none."""
    if not indices:
        return None
    return itemgetter(*(indices * 2)) if len(indices) == 1 else itemgetter(*indices)


# --- the walk: every value with its place on both sides ------------------------------------------------


class _Value(NamedTuple):
    """`number` values (a byte string: one value of `number` bytes) at `at_in` in the input and
    `at_out` in the output (after the prefix), `size_in`/`size_out` bytes each; `code_out` None:
    read only (a CDR count that LCM does not carry, the CDR header, the fingerprint)."""

    number: int
    code_in: str
    size_in: int
    at_in: int
    code_out: str | None
    size_out: int
    at_out: int
    role: str  # "", "shape", "text", "bool" (a CDR bool: checked) or "wide" (checked by the "q" pack)

    def struct_code(self, code: str) -> str:
        return f"{self.number}s" if code == "s" else f"{self.number}{code}"

    def values(self) -> int:
        return 1 if self.code_in == "s" else self.number


class _Walk:
    """The values of one message in the order both sides hold them, built field by field. The input
    is CDR and the output LCM of `fingerprint`, or, when that is None, the other way. Offsets count from the end of
    the fingerprint (LCM) or header (CDR, as it aligns)."""

    def __init__(self, data: bytes, fingerprint: bytes | None) -> None:
        self.data = data
        self.from_lcm = fingerprint is None
        self.prefix = CDR_HEADER if fingerprint is None else fingerprint  # the output's first bytes
        self.lcm = 0
        self.cdr = 0
        self.pieces: list[_Value] = []
        self.constants: list[tuple[int, bytes]] = []  # output-only bytes by output offset
        self.expected: list[Any] = []

    @property
    def start(self) -> int:
        """Where the input's first value is: after the fingerprint or the header."""
        return _FINGERPRINT if self.from_lcm else len(CDR_HEADER)

    def both(self, count: int, lcm: tuple[str, int], cdr: tuple[str, int], role: str = "") -> None:
        """`count` values held on both sides as (code, size) each; CDR aligns them (when any)."""
        if count and cdr[1] > 1:
            self.cdr += -self.cdr & (cdr[1] - 1)
        (code_in, size_in), at_in, (code_out, size_out), at_out = (
            (lcm, self.lcm, cdr, self.cdr) if self.from_lcm else (cdr, self.cdr, lcm, self.lcm)
        )
        self.pieces.append(
            _Value(count, code_in, size_in, self.start + at_in, code_out, size_out, at_out, role)
        )
        if role == "shape":
            self.expected.append(self.read_last())
        self.lcm += count * lcm[1]
        self.cdr += count * cdr[1]

    def read_last(self) -> Any:
        piece = self.pieces[-1]
        order = ">" if self.from_lcm else "<"
        return struct.unpack_from(order + piece.struct_code(piece.code_in), self.data, piece.at_in)[0]

    def shape(self, lcm: tuple[str, int], cdr: tuple[str, int]) -> int:
        """One value that fixes the shape, on both sides: its value in this message."""
        self.both(1, lcm, cdr, "shape")
        return int(self.expected[-1])

    def cdr_only(self, constant: bytes, align: int) -> None:
        """Bytes CDR has and LCM does not (a sequence's count, an empty message's byte): kept as a
        shape value when they are input, written as they are when output."""
        self.cdr += -self.cdr & (align - 1)
        if self.from_lcm:
            self.constants.append((self.cdr, constant))
        else:
            self.pieces.append(_Value(len(constant), "s", 1, len(CDR_HEADER) + self.cdr, None, 0, 0, "shape"))
            self.expected.append(constant)
        self.cdr += len(constant)

    def string(self) -> None:
        """LCM's big-endian length (counting the NUL), the bytes and the NUL; CDR's the same, its
        length little-endian and aligned to 4."""
        length = self.shape(("I", 4), ("I", 4))
        self.both(length - 1, ("s", 1), ("s", 1), "text")
        self.shape(("B", 1), ("B", 1))  # the NUL

    def layout(self) -> Layout | None:
        """The layout these values make, or None when no mover takes it."""
        if COMPILED_MOVER and len(program := self.program()) <= PROGRAM_BYTES:
            return program
        values = sum(piece.values() for piece in self.pieces)
        checked = not self.from_lcm and any(piece.role in ("bool", "wide") for piece in self.pieces)
        if not self.constants and values <= STRUCT_VALUES:
            return self.struct_layout()
        if not checked and (self.cdr if self.from_lcm else self.lcm) <= GATHER_BYTES:
            return self.gather_layout()
        return None

    def header(self) -> None:
        """The input's fingerprint or CDR header: a shape value, not written (the output's is the prefix)."""
        size = _FINGERPRINT if self.from_lcm else len(_CDR_LE)
        self.pieces.append(_Value(size, "s", 1, 0, None, 0, 0, "shape"))
        self.expected.append(self.data[:size])

    def struct_layout(self) -> PythonLayout:
        reads, writes = [">" if self.from_lcm else "<"], ["<" if self.from_lcm else ">"]
        read_to = write_to = index = 0
        key: list[int] = []
        bools: list[int] = []
        texts: list[int] = []
        for piece in self.pieces:
            code_in = "?" if piece.role == "bool" and self.from_lcm else piece.code_in
            reads.append(f"{piece.at_in - read_to}x{piece.struct_code(code_in)}")
            read_to = piece.at_in + piece.number * piece.size_in
            if piece.code_out is None:
                writes.append("0s")
            else:
                code_out = "?" if piece.role == "bool" and self.from_lcm else piece.code_out
                writes.append(f"{piece.at_out - write_to}x{piece.struct_code(code_out)}")
                write_to = piece.at_out + piece.number * piece.size_out
            indices = list(range(index, index + piece.values()))
            {"shape": key, "text": texts, "bool": bools}.get(piece.role, []).extend(indices)
            index += piece.values()
        return PythonLayout(
            read=struct.Struct("".join(reads)).unpack_from,
            key=_items(key),
            expected=tuple(self.expected) * (2 if len(key) == 1 else 1),
            bools=_items(bools) if not self.from_lcm else None,
            texts=_items(texts),
            prefix=self.prefix,
            write=struct.Struct("".join(writes)).pack,
            tail=b"",
            gather=None,
            normalize=None,
        )

    def gather_layout(self) -> PythonLayout:
        end = self.cdr if self.from_lcm else self.lcm
        prefix = self.prefix
        tail = bytearray(b"\0" + prefix)
        zero = len(self.data)
        gather = [zero + 1 + index for index in range(len(prefix))] + [zero] * end
        start = len(prefix)
        for at, constant in self.constants:
            gather[start + at : start + at + len(constant)] = range(
                zero + len(tail), zero + len(tail) + len(constant)
            )
            tail += constant
        reads, read_to, index = ["<>"[self.from_lcm]], 0, 0
        key: list[int] = []
        texts: list[int] = []
        normalize: list[int] = []
        for piece in self.pieces:
            if piece.role in ("shape", "text"):
                reads.append(f"{piece.at_in - read_to}x{piece.struct_code(piece.code_in)}")
                read_to = piece.at_in + piece.number * piece.size_in
                (key if piece.role == "shape" else texts).append(index)
                index += 1
            if piece.code_out is not None:
                for element in range(piece.number):
                    at = start + piece.at_out + element * piece.size_out
                    gather[at : at + piece.size_out] = self.moved(piece, element)
                    if piece.role == "bool":
                        normalize.append(at)
        return PythonLayout(
            read=struct.Struct("".join(reads)).unpack_from,
            key=itemgetter(*key) if texts else None,  # with a string: at least 3 values, a tuple
            expected=tuple(self.expected),
            bools=None,
            texts=_items(texts),
            prefix=b"",
            write=None,
            tail=bytes(tail),
            gather=np.array(gather, np.intp),
            normalize=np.array(normalize, np.intp) if normalize else None,
        )

    def program(self) -> MoveProgram:
        """The compiled mover's program: the output's template (prefix, constants, zeros), the
        input's checks (shape values, CDR bools, texts, wide integers) and its runs of values."""
        start = len(self.prefix)
        template = bytearray(self.prefix + bytes(self.cdr if self.from_lcm else self.lcm))
        for at, constant in self.constants:
            template[start + at : start + at + len(constant)] = constant
        checks: list[_Check] = []
        runs: list[_Run] = []
        expected = bytearray()
        for piece in self.pieces:
            span = piece.number * piece.size_in
            if piece.role == "shape":
                if checks and checks[-1][0] == _EQUAL and checks[-1][1] + checks[-1][2] == piece.at_in:
                    # one comparison
                    checks[-1] = (_EQUAL, checks[-1][1], checks[-1][2] + span, 1, checks[-1][4])
                else:
                    checks.append((_EQUAL, piece.at_in, span, 1, len(expected)))
                expected += self.data[piece.at_in : piece.at_in + span]
            elif piece.role == "text":
                checks.append((_UTF8, piece.at_in, span, 1, 0))
            elif piece.role == "bool" and not self.from_lcm:  # CDR: 0 or 1
                checks.append((_AT_MOST, piece.at_in, piece.number, 1, 1))
            elif piece.role == "wide":  # below 2^63: its top byte below 0x80 (little-endian: the last)
                top = 0 if self.from_lcm else piece.size_in - 1
                checks.append((_AT_MOST, piece.at_in + top, piece.number, piece.size_in, 0x7F))
            if piece.code_out is not None and piece.number:
                _add_run(runs, self.run(piece, start))
        words = [
            len(self.data),
            len(template),
            len(checks),
            len(runs),
            *(w for row in (*checks, *runs) for w in row),
        ]
        return MoveProgram(struct.pack(f"={len(words)}I", *words) + template + expected)

    def run(self, piece: _Value, start: int) -> _Run:
        """A piece's elements as a run: (in_at, out_at, count, in_step, out_step, width, flags). A
        wider output value (an unsigned CDR integer as LCM's next signed one) keeps the
        template's zeros in its high bytes: the first ones in big-endian LCM."""
        widened = piece.size_out - piece.size_in if not self.from_lcm else 0
        flags = _NONZERO if piece.role == "bool" and self.from_lcm else _SWAP if piece.size_in > 1 else 0
        return (piece.at_in, start + piece.at_out + widened, piece.number, piece.size_in, piece.size_out,
                piece.size_in, flags)  # fmt: skip

    def moved(self, piece: _Value, element: int) -> list[int]:
        """The input indices of one element's output bytes: reversed between the two byte
        orders, zero-extended when the output is wider (only unsigned CDR integers widen)."""
        first = piece.at_in + element * piece.size_in
        big_endian = list(range(first, first + piece.size_in))
        if piece.size_in > 1 and not self.from_lcm:
            big_endian.reverse()
        big_endian = [len(self.data)] * (piece.size_out - piece.size_in) + big_endian
        return big_endian[::-1] if self.from_lcm else big_endian


def _add_run(runs: list[_Run], run: _Run) -> None:
    """`run` after `runs`, as part of the last one when it goes on from it (a fixed array after its
    struct's numbers of the same type)."""
    if runs:
        in_at, out_at, count, in_step, out_step, width, flags = runs[-1]
        if run[:2] == (in_at + count * in_step, out_at + count * out_step) and run[3:] == runs[-1][3:]:
            runs[-1] = (in_at, out_at, count + run[2], in_step, out_step, width, flags)
            return
    runs.append(run)


# --- the walks over the two kinds of type ------------------------------------------------------------


def learn_lcm_layout(structs: Mapping[str, StructDef], name: str, data: bytes,
                     fingerprint: bytes | None = None) -> Layout | None:  # fmt: skip
    """The layout of `data`, that the generated code has passed: an LCM message of `name`, or,
    given its `fingerprint`, the CDR of its ROS 2 form; None when a layout does not take it."""
    if len(data) > LAYOUT_BYTES:
        return None
    walk = _Walk(data, fingerprint)
    walk.header()
    _lcm_struct(walk, structs, name)
    return walk.layout()


def _lcm_struct(walk: _Walk, structs: Mapping[str, StructDef], name: str) -> None:
    definition = structs[name]
    if not definition.members:  # ROS 2 gives an empty message one uint8
        walk.cdr_only(b"\0", 1)
    lengths = {dim.size for member in definition.members for dim in member.dims if dim.is_variable}
    values: dict[str, int] = {}
    for member in definition.members:
        if not member.dims:
            if member.name in lengths:
                side = (_LCM_CODES[member.type_name], PRIMITIVE_FORMATS[member.type_name][1])
                values[member.name] = walk.shape(side, side)
            else:
                _lcm_elements(walk, structs, member, 1)
            continue
        count = math.prod(values[dim.size] if dim.is_variable else dim.count for dim in member.dims)
        if not (len(member.dims) == 1 and not member.dims[0].is_variable):  # a sequence: its count
            walk.cdr_only(count.to_bytes(4, "little"), 4)
        _lcm_elements(walk, structs, member, count)


def _lcm_elements(walk: _Walk, structs: Mapping[str, StructDef], member: Member, count: int) -> None:
    if member.type_name in PRIMITIVE_FORMATS:
        size = PRIMITIVE_FORMATS[member.type_name][1]
        side = (
            ("s", 1) if size == 1 and member.type_name != "boolean" else (_LCM_CODES[member.type_name], size)
        )
        walk.both(count, side, side, "bool" if member.type_name == "boolean" else "")
        return
    for _ in range(count):
        if member.type_name == "string":
            walk.string()
        else:
            _lcm_struct(walk, structs, member.type_name)


def learn_ros_layout(structs: Mapping[str, RosStruct], wire: Wire, ros_name: str, fingerprint: bytes,
                     data: bytes) -> Layout | None:  # fmt: skip
    """The layout of `data`, the CDR of a ROS 2 message of `ros_name` that the generated code has
    passed, as its LCM form; None when a layout does not take it (a wstring: its LCM length is
    not its CDR one)."""
    if len(data) > LAYOUT_BYTES:
        return None
    walk = _Walk(data, fingerprint)
    walk.header()
    try:
        _ros_struct(walk, structs, wire, ros_name)
    except NoLayout:
        return None
    return walk.layout()


def _ros_struct(walk: _Walk, structs: Mapping[str, RosStruct], wire: Wire, name: str) -> None:
    for ros_field in structs[name].fields:
        if ros_field.kind == "scalar":
            _ros_element(walk, structs, wire, ros_field)
            continue
        count = ros_field.count if ros_field.kind == "array" else walk.shape(("i", 4), ("I", 4))
        if ros_field.base in wire:
            _ros_numbers(walk, wire, ros_field.base, count)
        else:
            for _ in range(count):
                _ros_element(walk, structs, wire, ros_field)


def _ros_element(walk: _Walk, structs: Mapping[str, RosStruct], wire: Wire, ros_field: RosField) -> None:
    if ros_field.nested:
        _ros_struct(walk, structs, wire, ros_field.nested)
    elif ros_field.base == "string":
        walk.string()
    elif ros_field.base == "wstring":
        raise NoLayout
    else:
        _ros_numbers(walk, wire, ros_field.base, 1)


def _ros_numbers(walk: _Walk, wire: Wire, base: str, count: int) -> None:
    size, little, big = wire[base]
    if size == 1 and base != "bool":  # bytes: LCM's are CDR's
        walk.both(count, ("s", 1), ("s", 1))
        return
    role = {"bool": "bool", "uint64": "wide"}.get(base, "")
    walk.both(count, (big, struct.calcsize(big)), (little, size), role)
