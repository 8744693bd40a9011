"""The protobuf wire format by hand, for the encoders that write bytes without message objects.

A message is its fields' encodings in field-number order, as protobuf's own writer (upb) lays
it out, so pieces serialised once can be joined (`ign.model.model_bytes`) or rewritten in
place (`ign.poses.PosesEncoder`), and the bytes equal protobuf's. proto3 leaves out a scalar equal to its
default, judged by bit pattern (so -0.0 is written); a submessage that was set is written even
when empty. The helpers here follow both rules. (Foxglove's SceneUpdate was tried this way and
was no faster than its protobuf objects: it stays with those.)
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from math import copysign

VARINT, FIXED64, LENGTH_DELIMITED, FIXED32 = 0, 1, 2, 5  # wire types
_SMALL_VARINTS = [bytes((value,)) for value in range(0x80)]
_DOUBLE = struct.Struct("<d")


def varint(value: int) -> bytes:
    """A base-128 varint; a negative value is written as its 64-bit two's complement, as int64 is."""
    if 0 <= value < 0x80:
        return _SMALL_VARINTS[value]
    value &= 0xFFFFFFFFFFFFFFFF
    out = bytearray()
    while value > 0x7F:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def key(number: int, wire_type: int) -> bytes:
    return varint((number << 3) | wire_type)


def submessage(field_key: bytes, payload: bytes) -> bytes:
    """A length-delimited field (a message, string or bytes), written even when empty."""
    return field_key + varint(len(payload)) + payload


def length_delimited(number: int, payload: bytes) -> bytes:
    """`submessage` by field number."""
    return submessage(key(number, LENGTH_DELIMITED), payload)


def varint_field(number: int, value: int) -> bytes:
    """A varint field, left out when it is 0 (proto3)."""
    return key(number, VARINT) + varint(value) if value else b""


def string_field(field_key: bytes, text: str) -> bytes:
    """A proto3 string field: left out when empty."""
    return submessage(field_key, text.encode()) if text else b""


def double_keys(first: int, count: int) -> list[bytes]:
    """The keys of `count` double fields numbered from `first` (x, y, z[, w] of a vector)."""
    return [key(number, FIXED64) for number in range(first, first + count)]


def doubles(keys: Sequence[bytes], values: Sequence[float]) -> bytes:
    """Double fields, each left out when its bits are all zero (0.0, not -0.0)."""
    pairs = zip(keys, values, strict=False)  # keys may be longer: a Vector3 uses 3 of 4
    return b"".join(
        [field + _DOUBLE.pack(value) for field, value in pairs if value or copysign(1.0, value) < 0]
    )


class PoseWriter:
    """A Pose message {position: Vector3, orientation: Quaternion} for given field numbers.

    The common pose has no zero in it; its bytes then have a fixed layout, packed in one call.
    """

    def __init__(self, position: int, orientation: int, first_component: int) -> None:
        self.position_key = key(position, LENGTH_DELIMITED)
        self.orientation_key = key(orientation, LENGTH_DELIMITED)
        self.vector_keys = double_keys(first_component, 3)
        self.quaternion_keys = double_keys(first_component, 4)
        parts = (self.position_key, self.orientation_key, *self.quaternion_keys)
        assert all(len(part) == 1 for part in parts)  # field numbers below 16: one byte each
        vector = [item[0] for item in self.vector_keys]
        quaternion = [item[0] for item in self.quaternion_keys]
        self._codes = [self.position_key[0], 27, *vector, self.orientation_key[0], 36, *quaternion]
        self._full = struct.Struct("<BB" + "Bd" * 3 + "BB" + "Bd" * 4)

    def pose(self, x: float, y: float, z: float, qx: float, qy: float, qz: float, qw: float) -> bytes:
        """The pose's fields (quaternion x, y, z, w); zeros left out by bit pattern."""
        if x and y and z and qx and qy and qz and qw:  # NaN is truthy and written, as protobuf does
            p, l3, kx, ky, kz, o, l4, ox, oy, oz, ow = self._codes
            return self._full.pack(p, l3, kx, x, ky, y, kz, z, o, l4, ox, qx, oy, qy, oz, qz, ow, qw)
        position = submessage(self.position_key, doubles(self.vector_keys, (x, y, z)))
        return position + submessage(self.orientation_key, doubles(self.quaternion_keys, (qx, qy, qz, qw)))


def exact_key(values: Sequence[float]) -> bytes:
    """Floats as a dict key for caching their encoding: 0.0 and -0.0 are equal as floats (and
    hash alike) but are written differently, so the key is their bits."""
    return struct.pack(f"<{len(values)}d", *values)
