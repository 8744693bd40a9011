"""The layout of an LCM message as CDR, for the LCM -> CDR fast path (`cdr.CdrTranscoder`).

`ros_layout` backwards, with a different last step. A stream of one LCM type mostly repeats its
shape: a robot's status has the same joint count, so the same array lengths, message after
message; only numbers change. Once a message has passed the generated code (every check, every
error named), its layout is found here by walking the type over its bytes: where each CDR byte
comes from, and the values that fix the shape (the fingerprint, each length field, each
string's length and NUL) with what they were. A later message of the same size whose shape
values are the same has the same layout (each position follows from the ones before it), so it
is one `struct` read of its shape values, one tuple comparison, a UTF-8 check of its strings
and one gather of its bytes.

Why a gather of bytes (numpy indexing by a kept index array) and not `ros_layout`'s one unpack and
one pack of every value: every CDR byte is an LCM byte moved (a big-endian number's bytes
reversed, a string's bytes as they are) or a constant of the shape (the header, a sequence's
count, padding), and moving bytes makes no Python object per number. Measured on
`lcmt_iiwa_status` (49 doubles) in one process: one unpack and one pack of every value took 0.6
to 0.75 of the generated code's time (and would need each sequence's count put in), the gather
0.35 to 0.45. Bools are the one value that changes: LCM reads any byte other than 0 as true,
CDR writes 1.

What a layout does not take: messages above `LAYOUT_BYTES` (the generated code swaps long arrays in
one call, and an index is 8 bytes per byte of the message).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Mapping
from operator import itemgetter
from typing import Any, NamedTuple

import numpy as np

from viewer_bridge.lcmcodec.schema import PRIMITIVE_FORMATS, Member, StructDef

__all__ = ["LAYOUT_BYTES", "CdrLayout", "learn_cdr_layout"]

LAYOUT_BYTES = 4096
_FINGERPRINT = 8
_CDR_HEADER = b"\x00\x01\x00\x00"  # cdr.CDR_HEADER (not imported: cdr imports this module)


class CdrLayout(NamedTuple):  # a tuple: unpacked at once on the fast path
    """Where every CDR byte of the LCM messages of one size and shape comes from, kept once one has
    passed the generated code: a message of that size whose shape values are `expected` (read
    by `read`, picked by `key` when it reads strings too) has the same layout, and is valid if its
    `texts` are UTF-8. Its CDR is `(message + tail)[gather]`, with 1 for any bool byte not 0."""

    read: Callable[[bytes], tuple[Any, ...]]  # the shape values, and each string's bytes
    key: Callable[[tuple[Any, ...]], tuple[Any, ...]] | None  # the shape values; None: `read` reads nothing else
    expected: tuple[Any, ...]
    texts: Callable[[tuple[Any, ...]], tuple[bytes, ...]] | None  # each string's bytes: must be UTF-8
    tail: bytes  # the constant bytes: header, counts, a zero for padding
    gather: np.ndarray[Any, np.dtype[np.intp]]  # each CDR byte's index in message + tail
    bools: np.ndarray[Any, np.dtype[np.intp]] | None  # the CDR positions of bools


class _Walk:
    """The gather index, shape values and checks of one message, built member by member."""

    def __init__(self, structs: Mapping[str, StructDef], data: bytes) -> None:
        self.structs = structs
        self.data = data
        self.off = _FINGERPRINT  # LCM offset
        self.pos = 0  # CDR position, from the end of the header (as CDR aligns)
        self.tail = bytearray(_CDR_HEADER + b"\0")
        self.gather = [len(data) + index for index in range(4)]
        self.reads = [f">{_FINGERPRINT}s"]
        self.read_to = _FINGERPRINT  # where `reads` has got to in the message
        self.values = 1
        self.key = [0]
        self.expected: list[Any] = [data[:_FINGERPRINT]]
        self.texts: list[int] = []
        self.bools: list[int] = []

    def read(self, code: str, at: int, size: int) -> int:
        """One value of `size` bytes at LCM offset `at` for the fast path to read; its index."""
        self.reads.append(f"{at - self.read_to}x{code}")
        self.read_to = at + size
        self.values += 1
        return self.values - 1

    def shape(self, code: str, at: int, size: int) -> Any:
        """A value that fixes the shape: its value in this message is expected in the others."""
        self.key.append(self.read(code, at, size))
        self.expected.append(struct.unpack_from(">" + code, self.data, at)[0])
        return self.expected[-1]

    def pad(self, size: int) -> None:
        pad = -self.pos & (size - 1)
        self.gather += [len(self.data) + 4] * pad  # the tail's zero
        self.pos += pad

    def constant(self, value: bytes) -> None:
        self.gather += range(len(self.data) + len(self.tail), len(self.data) + len(self.tail) + len(value))
        self.tail += value
        self.pos += len(value)

    def moved(self, size: int, reverse: bool) -> None:
        """`size` LCM bytes at the offset to the CDR position, reversed when a big-endian number."""
        self.gather += range(self.off + size - 1, self.off - 1, -1) if reverse else range(self.off, self.off + size)
        self.off += size
        self.pos += size

    def struct_(self, name: str) -> None:
        definition = self.structs[name]
        if not definition.members:  # ROS 2 gives an empty message one uint8
            self.constant(b"\0")
        lengths = {dim.size for member in definition.members for dim in member.dims if dim.is_variable}
        values: dict[str, int] = {}
        for member in definition.members:
            if not member.dims:
                if member.name in lengths:
                    values[member.name] = self.shape(PRIMITIVE_FORMATS[member.type_name][0], self.off,
                                                     PRIMITIVE_FORMATS[member.type_name][1])  # fmt: skip
                self.element(member)
                continue
            count = math.prod(values[dim.size] if dim.is_variable else dim.count for dim in member.dims)
            if not (len(member.dims) == 1 and not member.dims[0].is_variable):  # a sequence: its count
                self.pad(4)
                self.constant(count.to_bytes(4, "little"))
            if count and member.type_name in PRIMITIVE_FORMATS:  # an empty array is not aligned
                self.pad(PRIMITIVE_FORMATS[member.type_name][1])
            for _ in range(count):
                self.element(member)

    def element(self, member: Member) -> None:
        if member.type_name == "string":
            self.string()
        elif member.type_name in PRIMITIVE_FORMATS:
            size = PRIMITIVE_FORMATS[member.type_name][1]
            self.pad(size)
            if member.type_name == "boolean":
                self.bools.append(4 + self.pos)
            self.moved(size, reverse=size > 1)
        else:
            self.struct_(member.type_name)

    def string(self) -> None:
        """LCM's big-endian length (counting the NUL), the bytes and the NUL; CDR's the same, its
        length little-endian and aligned to 4."""
        length = self.shape("I", self.off, 4)
        self.texts.append(self.read(f"{length - 1}s", self.off + 4, length - 1))
        self.shape("B", self.off + 3 + length, 1)  # the NUL
        self.pad(4)
        self.moved(4, reverse=True)
        self.moved(length, reverse=False)

    def layout(self) -> CdrLayout:
        texts = self.texts
        return CdrLayout(
            read=struct.Struct("".join(self.reads)).unpack_from,
            key=itemgetter(*self.key) if texts else None,  # with a string: at least 3 values, a tuple
            expected=tuple(self.expected),
            texts=(itemgetter(*texts * 2) if len(texts) == 1 else itemgetter(*texts)) if texts else None,
            tail=bytes(self.tail),
            gather=np.array(self.gather, np.intp),
            bools=np.array(self.bools, np.intp) if self.bools else None,
        )


def learn_cdr_layout(structs: Mapping[str, StructDef], name: str, data: bytes) -> CdrLayout | None:
    """The layout of `data`, an LCM message of `name` that the generated code has passed; None
    when a layout does not take it. (`cdr.CdrTranscoder.transcode` applies it.)"""
    if len(data) > LAYOUT_BYTES:
        return None
    walk = _Walk(structs, data)
    walk.struct_(name)
    return walk.layout()
