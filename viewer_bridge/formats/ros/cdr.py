"""ROS 2 CDR written and read directly, for the fast paths: the little-endian header, the
`builtin_interfaces/Time` stamp (`CDR_TIME`, `time_parts`), strings, a chunked writer, a checked
reader, and numpy views of a message's poses and stamps.

Messages as rosbags objects (`make`, `to_cdr`, ...) are in `viewer_bridge.formats.ros.messages`.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError, EncodeError
from viewer_bridge.model.sim_time import sec_nsec_from_ms, sec_nsec_from_us, us_from_sec_nsec

CDR_LE = b"\x00\x01\x00\x00"  # the encapsulation header: little-endian plain CDR
U32 = struct.Struct("<I")
CDR_TIME = struct.Struct("<iI")  # builtin_interfaces/Time in little-endian CDR: int32 sec, uint32 nanosec
POSE_ITEM = np.dtype((np.void, 56))  # geometry_msgs/Pose or Transform: 7 float64, as one item
# Bytes in front of a message in a buffer, so that its 8-aligned payload offsets are aligned in memory.
FRONT_PADDING = 4


def time_parts(timestamp_ms: int) -> tuple[int, int]:
    """Drake's millisecond sim time as `builtin_interfaces/Time` (int32 sec, uint32 nanosec).

    Raises `EncodeError` for a time whose seconds do not fit an int32.
    """
    return _int32_seconds(sec_nsec_from_ms(timestamp_ms), f"{timestamp_ms} ms")


def time_parts_from_us(time_us: int) -> tuple[int, int]:
    """A microsecond time (Drake's `utime`) as `builtin_interfaces/Time`; `EncodeError` as above."""
    return _int32_seconds(sec_nsec_from_us(time_us), f"{time_us} us")


def _int32_seconds(parts: tuple[int, int], what: str) -> tuple[int, int]:
    if not -(2**31) <= parts[0] < 2**31:
        raise EncodeError("builtin_interfaces/msg/Time", "sec", f"{what} does not fit int32 seconds")
    return parts


def payload_items(buffer: Any, item: np.dtype[Any], step: int, front: int = 0) -> np.ndarray[Any, Any]:
    """A writable view of `buffer` (a message after `front` spare bytes) as items of `item`'s size,
    one starting every `step` bytes of the payload (after the 4-byte encapsulation, where CDR's
    alignment counts from); they overlap when the item is longer than the step. Writing item k
    writes bytes `step * k` onwards of the payload: a whole pose or stamp in one copy."""
    payload = front + len(CDR_LE)
    count = max(0, (len(buffer) - payload - item.itemsize) // step + 1)
    return np.ndarray((count,), dtype=item, buffer=buffer, offset=payload, strides=(step,))


def cdr_string(text: str, field: str = "string") -> bytes:
    """A CDR string: uint32 length counting the NUL, the UTF-8 bytes, the NUL.

    Raises `EncodeError` for text with a NUL in it (a reader would stop there) or that is not
    valid Unicode.
    """
    if "\0" in text:
        raise EncodeError("CDR", field, f"{text!r} contains a NUL character, which a CDR string cannot carry")
    try:
        data = text.encode("utf-8") + b"\0"
    except UnicodeEncodeError as error:  # a lone surrogate
        raise EncodeError("CDR", field, f"{text!r} is not valid Unicode ({error.reason})") from None
    return U32.pack(len(data)) + data


def cdr_string_4(text: str, field: str = "string") -> bytes:
    """A CDR string padded to a multiple of 4, for a string that starts 4-aligned."""
    data = cdr_string(text, field)
    return data + b"\0" * (-len(data) % 4)


class CdrWriter:
    """Little-endian CDR into a list of chunks; `size` is the payload offset alignment counts from."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = [CDR_LE]
        self.size = 0

    def add(self, data: bytes) -> None:
        self.chunks.append(data)
        self.size += len(data)

    def align(self, boundary: int) -> None:
        padding = -self.size % boundary
        if padding:
            self.add(b"\0" * padding)

    def pack(self, layout: struct.Struct, *values: Any) -> None:
        self.align(4)  # every layout used here starts with a 4-byte value
        self.add(layout.pack(*values))

    def string(self, text: str, field: str = "string") -> None:
        self.align(4)
        self.add(cdr_string(text, field))  # checked: no NUL, valid Unicode

    def octets(self, data: bytes) -> None:
        self.pack(U32, len(data))
        self.add(data)

    def getvalue(self) -> bytes:
        return b"".join(self.chunks)


class CdrReader:
    """CDR of either byte order from a buffer, every read checked against the bytes left.

    Alignment counts from after the 4-byte encapsulation header, as when writing. Bytes that do
    not fit raise `DecodeError` naming `type_name`, the field and the offset.
    """

    def __init__(self, data: bytes | memoryview, type_name: str) -> None:
        self.buffer = memoryview(data).cast("B")
        self.type_name = type_name
        if len(self.buffer) < 4 or self.buffer[0] != 0 or self.buffer[1] not in (0, 1):
            raise DecodeError(type_name, "", 0, "not CDR (encapsulation 00 00 or 00 01)")
        self.big_endian = self.buffer[1] == 0
        self.order = ">" if self.big_endian else "<"
        self.offset = 4

    def take(self, size: int, alignment: int, field: str) -> int:
        """The offset of the next `size` bytes at `alignment`, which are then consumed."""
        start = 4 + -(-(self.offset - 4) // alignment) * alignment
        if start + size > len(self.buffer):
            left = max(len(self.buffer) - start, 0)
            raise DecodeError(self.type_name, field, start, f"needs {size} bytes, {left} left")
        self.offset = start + size
        return start

    def scalar(self, code: str, field: str) -> Any:
        size = struct.calcsize(code)
        return struct.unpack_from(self.order + code, self.buffer, self.take(size, size, field))[0]

    def boolean(self, field: str) -> bool:
        value = self.buffer[self.take(1, 1, field)]
        if value > 1:
            raise DecodeError(self.type_name, field, self.offset - 1, f"bool is {value}, not 0 or 1")
        return bool(value)

    def string(self, field: str) -> str:
        length = self.scalar("I", field)
        if length == 0:
            raise DecodeError(self.type_name, field, self.offset - 4, "string length 0 (the NUL is counted)")
        start = self.take(length, 1, field)
        raw = self.buffer[start : start + length]
        if raw[-1] != 0:
            raise DecodeError(self.type_name, field, start, "string does not end with NUL")
        try:
            return str(raw[:-1], "utf-8")
        except UnicodeDecodeError as error:
            raise DecodeError(self.type_name, field, start + error.start, "string is not UTF-8") from None

    def header(self) -> tuple[int, str]:
        """A `std_msgs/Header`: its stamp in microseconds and its frame id."""
        seconds = self.scalar("i", "header.stamp.sec")
        nanoseconds = self.scalar("I", "header.stamp.nanosec")
        if nanoseconds >= 1_000_000_000:
            raise DecodeError(
                self.type_name, "header.stamp.nanosec", self.offset - 4, f"{nanoseconds} >= 1e9"
            )
        return us_from_sec_nsec(seconds, nanoseconds), self.string("header.frame_id")

    def count(self, field: str, item_size: int) -> int:
        """A sequence length, refused before anything is allocated if its items cannot fit."""
        count = int(self.scalar("I", field))
        left = len(self.buffer) - self.offset
        if count * item_size > left:
            raise DecodeError(
                self.type_name,
                field,
                self.offset - 4,
                f"count {count} needs {count * item_size} bytes, {left} left",
            )
        return count

    def octets(self, field: str) -> memoryview:
        length = self.count(field, 1)
        start = self.take(length, 1, field)
        return self.buffer[start : start + length]
