"""The protobuf wire format, for the encoders that write bytes without message objects.

Only what those encoders need: varints, field keys, length-delimited fields. A proto3 writer
(protobuf's own, upb) leaves out a scalar equal to its default (0, +0.0, "") and writes
fields in field-number order; the fast encoders do the same so their bytes equal protobuf's.
"""

from __future__ import annotations

VARINT, FIXED64, LENGTH_DELIMITED = 0, 1, 2  # wire types


def varint(value: int) -> bytes:
    """A base-128 varint; a negative value is written as its 64-bit two's complement, as int64 is."""
    value &= 0xFFFFFFFFFFFFFFFF
    out = bytearray()
    while True:
        byte, value = value & 0x7F, value >> 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def key(field: int, wire_type: int) -> bytes:
    return varint(field << 3 | wire_type)


def length_delimited(field: int, payload: bytes) -> bytes:
    return key(field, LENGTH_DELIMITED) + varint(len(payload)) + payload


def varint_field(field: int, value: int) -> bytes:
    """A varint field, left out when it is 0 (proto3)."""
    return key(field, VARINT) + varint(value) if value else b""
