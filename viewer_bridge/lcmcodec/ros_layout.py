"""The layout of a ROS 2 CDR message, for the CDR -> LCM fast path (`cdr_to_lcm.LcmEncoder`).

A stream of one ROS 2 type mostly repeats its shape: a robot's `JointState` has the same joint
names, so the same counts and string lengths, message after message; only numbers change. Once a
message has passed the generated code (every check, every error named), its layout is found here
by walking the type over its bytes: one little-endian `struct` that reads every value of the
message, one big-endian `struct` that writes them as LCM, and the values that fix the shape (the
header, each count, each string's length and NUL) with what they were. A later message of the
same size whose shape values are the same has the same layout (each position follows from the
ones before it), so it is one unpack, one tuple comparison, a check of its bools and strings
(one UTF-8 decode of them all) and one pack.

What a layout does not take: a `wstring` (its LCM length is not its CDR one), messages above
`_BYTES` (a layout copies the bytes twice where the generated code copies them once) or holding
more than `_VALUES` numbers (the generated code swaps long arrays in one call).
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from operator import itemgetter
from typing import Any

from viewer_bridge.lcmcodec.cdr_to_lcm import Layout, items
from viewer_bridge.lcmcodec.from_ros import RosField, RosStruct

__all__ = ["learn_layout"]

_HEADER = 4
_BYTES = 16384
_VALUES = 512
# ROS 2 primitive -> (CDR size, little-endian code, LCM's big-endian code): `ros_cdr._WIRE`'s, read
# there; a uint64 from 2^63 up makes the "q" pack raise, and the encoder then takes the slow path.
Wire = Mapping[str, tuple[int, str, str]]


class _NoLayout(Exception):
    """The message holds something a layout does not take."""


class _Walk:
    """The formats, shape values and checks of one message, built field by field."""

    def __init__(self, structs: Mapping[str, RosStruct], wire: Wire, data: bytes) -> None:
        self.structs = structs
        self.wire = wire
        self.data = data
        self.position = 0  # from the end of the header, as CDR aligns
        self.little = ["<2s2x"]  # the representation (checked by the key), the options (not read)
        self.big = [">0s"]  # the representation goes nowhere
        self.key = [0]
        self.expected: list[Any] = [b"\x00\x01"]
        self.bools: list[int] = []
        self.strings: list[int] = []
        self.values = 1

    def value(self, little: str, big: str, size: int, count: int = 1) -> int:
        """`count` values of `size` bytes each, aligned to `size`; returns the index of the first."""
        if self.values > _VALUES:
            raise _NoLayout
        pad = -self.position & (size - 1) if size > 1 else 0
        self.little.append("x" * pad + little)
        self.big.append(big)
        self.position += pad
        first = self.values
        self.values += count
        return first

    def shape(self, little: str, big: str, size: int) -> int:
        """One value that fixes the shape: its value in this message is expected in the others."""
        index = self.value(little, big, size)
        self.key.append(index)
        self.expected.append(struct.unpack_from("<" + little, self.data, _HEADER + self.position)[0])
        self.position += size
        return int(self.expected[-1])

    def struct_(self, name: str) -> None:
        for ros_field in self.structs[name].fields:
            if ros_field.kind == "scalar":
                self.element(ros_field)
                continue
            count = ros_field.count if ros_field.kind == "array" else self.shape("I", "i", 4)
            if ros_field.base in self.wire:
                self.numbers(ros_field.base, count)
            else:
                for _ in range(count):
                    self.element(ros_field)

    def element(self, ros_field: RosField) -> None:
        if ros_field.nested:
            self.struct_(ros_field.nested)
        elif ros_field.base == "string":
            length = self.shape("I", "I", 4)
            self.strings.append(self.value(f"{length - 1}s", f"{length - 1}s", 1))
            self.position += length - 1
            self.shape("B", "B", 1)  # the NUL
        elif ros_field.base == "wstring":
            raise _NoLayout
        else:
            self.numbers(ros_field.base, 1)

    def numbers(self, base: str, count: int) -> None:
        """`count` numbers of `base` (none aligned when there are none); bytes in one piece."""
        if not count:
            return
        size, little, big = self.wire[base]
        if size == 1 and base != "bool":  # bytes: LCM's are CDR's
            self.value(f"{count}s", f"{count}s", 1)
        else:
            first = self.value(f"{count}{little}", f"{count}{big}", size, count)
            if base == "bool":
                self.bools.extend(range(first, first + count))
        self.position += size * count

    def layout(self) -> Layout:
        trailing = len(self.data) - _HEADER - self.position  # rclpy's padding to a multiple of 4
        return Layout(
            read=struct.Struct("".join(self.little) + "x" * trailing).unpack_from,
            key=itemgetter(0, *self.key),  # the header twice: a tuple even when it is the whole key
            expected=(self.expected[0], *self.expected),
            bools=items(self.bools),
            texts=items(self.strings),
            write=struct.Struct("".join(self.big)).pack,
        )


def learn_layout(structs: Mapping[str, RosStruct], wire: Wire, ros_name: str, data: bytes) -> Layout | None:
    """The layout of `data`, a CDR message of `ros_name` that the generated code has passed; None
    when a layout does not take it."""
    if len(data) > _BYTES:
        return None
    walk = _Walk(structs, wire, data)
    try:
        walk.struct_(ros_name)
    except _NoLayout:
        return None
    return walk.layout()
