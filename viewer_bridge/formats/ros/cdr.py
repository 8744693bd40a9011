"""ROS 2 CDR read directly, for the fast paths, and what the templates of the writers share: the
`builtin_interfaces/Time` stamp (`CDR_TIME`, `time_parts`), a checked reader, and numpy views of a
message's poses and stamps.

CDR is written by the generated writer (`viewer_bridge.lcmcodec.ros_writer`); messages as
rosbags objects (`make`, `to_cdr`, ...) are in `viewer_bridge.formats.ros.messages`.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError, EncodeError
from viewer_bridge.lcmcodec.codegen import CDR_LE
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.sim_time import sec_nsec_from_ms, sec_nsec_from_us, us_from_sec_nsec

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


class StampedTemplate:
    """A message with a `header` written once by the generated writer, whose stamp each call
    replaces (`stamped`); `at[path]` is where each other marked field starts in the message's
    bytes (the encapsulation counted), e.g. a last field cut off and written per call."""

    def __init__(self, type_name: str, value: Any, marks: tuple[str, ...] = ()) -> None:
        message, found = ros_writer(type_name, ("header.stamp", *marks)).write_marked(value)
        start = len(CDR_LE) + found["header.stamp"][0]  # marks count from after the encapsulation
        self._head, self._tail = message[:start], message[start + CDR_TIME.size :]
        self.at = {path: len(CDR_LE) + found[path][0] for path in marks}

    def stamped(self, stamp: tuple[int, int]) -> bytes:
        """The message stamped `stamp` (sec, nanosec)."""
        return b"".join((self._head, CDR_TIME.pack(*stamp), self._tail))


def payload_items(buffer: Any, item: np.dtype[Any], step: int, front: int = 0) -> np.ndarray[Any, Any]:
    """A writable view of `buffer` (a message after `front` spare bytes) as items of `item`'s size,
    one starting every `step` bytes of the payload (after the 4-byte encapsulation, where CDR's
    alignment counts from); they overlap when the item is longer than the step. Writing item k
    writes bytes `step * k` onwards of the payload: a whole pose or stamp in one copy."""
    payload = front + len(CDR_LE)
    count = max(0, (len(buffer) - payload - item.itemsize) // step + 1)
    return np.ndarray((count,), dtype=item, buffer=buffer, offset=payload, strides=(step,))


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
