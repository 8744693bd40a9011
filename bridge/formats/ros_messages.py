"""ROS 2 message plumbing: build any Jazzy message, turn it into CDR or an rclpy object.

Messages are rosbags dataclasses (pure Python, every Jazzy type, CDR included), so everything
here works without a ROS installation; `to_rclpy` needs the ROS 2 message packages. The CDR
helpers at the end are for the fast paths in `bridge.formats.ros`, which write bytes directly.
"""

from __future__ import annotations

import importlib
import struct
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

from bridge.errors import DecodeError, EncodeError
from bridge.sim_time import sec_nsec_from_ms, sec_nsec_from_us

STORE = get_typestore(Stores.ROS2_JAZZY)

# --- building messages ---------------------------------------------------------------------------


def make(typename: str, **values: Any) -> Any:
    """A rosbags message of `typename`; fields not given take ROS's defaults (0, "", empty).

    Numeric array fields may be given as lists; they become the numpy arrays rosbags expects.
    """
    for name, default in _defaults(typename).items():
        if name not in values:
            values[name] = default()
    for name, dtype in _array_dtypes(typename).items():
        if not isinstance(values[name], np.ndarray):
            values[name] = np.asarray(values[name], dtype=dtype)
    return STORE.types[typename](**values)


@cache
def _defaults(typename: str) -> dict[str, Callable[[], Any]]:
    _, field_defs = STORE.fielddefs[typename]
    return {name: _default_of(definition) for name, definition in field_defs}


@cache
def _array_dtypes(typename: str) -> dict[str, np.dtype[Any]]:
    """The fields of `typename` that rosbags holds as numpy arrays, with their dtypes."""
    samples = {name: default() for name, default in _defaults(typename).items()}
    return {name: value.dtype for name, value in samples.items() if isinstance(value, np.ndarray)}


def _default_of(definition: tuple[Any, Any]) -> Callable[[], Any]:
    node, detail = definition
    if node == Nodetype.BASE:
        base = detail[0]
        value: Any = "" if base == "string" else False if base == "bool" else 0.0 if "float" in base else 0
        return lambda: value
    if node == Nodetype.NAME:
        return lambda: make(detail)
    (item_node, item_detail), length = detail
    if item_node == Nodetype.BASE and item_detail[0] != "string":
        dtype = np.dtype(_NUMPY_TYPES.get(item_detail[0], item_detail[0]))
        size = length if node == Nodetype.ARRAY else 0
        return lambda: np.zeros(size, dtype=dtype)
    if node == Nodetype.ARRAY:
        item = _default_of((item_node, item_detail))
        return lambda: [item() for _ in range(length)]
    return list


_NUMPY_TYPES = {"byte": "uint8", "octet": "uint8", "char": "uint8", "bool": "bool"}


CDR_TIME = struct.Struct("<iI")  # builtin_interfaces/Time in little-endian CDR: int32 sec, uint32 nanosec


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


def stamp(timestamp_ms: int) -> Any:
    """A `builtin_interfaces/Time` for Drake's millisecond sim time."""
    seconds, nanoseconds = time_parts(timestamp_ms)
    return make("builtin_interfaces/msg/Time", sec=seconds, nanosec=nanoseconds)


def to_cdr(message: Any) -> bytes:
    """Little-endian CDR with its 4-byte encapsulation header, as rclpy publishes and reads it."""
    return bytes(STORE.serialize_cdr(message, message.__msgtype__))


def from_cdr(data: bytes | memoryview, typename: str) -> Any:
    """Raw CDR as a rosbags message; raises `DecodeError` for bytes that are not one."""
    try:
        return STORE.deserialize_cdr(bytes(data), typename)
    except Exception as error:  # rosbags raises struct.error, IndexError, ... on bad bytes
        raise DecodeError(typename, "", 0, f"not a valid CDR message: {error}") from None


def to_rclpy(message: Any) -> Any:
    """The same message as an rclpy message object (needs the ROS 2 message packages)."""
    package, _, name = message.__msgtype__.split("/")
    cls = getattr(importlib.import_module(f"{package}.msg"), name)
    values = {item.name: _rclpy_value(getattr(message, item.name)) for item in fields(message)}
    return cls(**values)


def _rclpy_value(value: Any) -> Any:
    if is_dataclass(value):
        return to_rclpy(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [_rclpy_value(item) for item in value]
    return value


def from_rclpy(message: Any) -> Any:
    """An rclpy message object as the rosbags message of the same type."""
    module, name = type(message).__module__, type(message).__name__
    typename = f"{module.split('.')[0]}/msg/{name}"
    _, field_defs = STORE.fielddefs[typename]
    values = {}  # numeric arrays (array.array, numpy) are made numpy arrays by `make`
    for field_name, _ in field_defs:
        value = getattr(message, field_name)
        if isinstance(value, list):
            value = [
                from_rclpy(item) if hasattr(item, "get_fields_and_field_types") else item for item in value
            ]
        elif hasattr(value, "get_fields_and_field_types"):
            value = from_rclpy(value)
        values[field_name] = value
    return make(typename, **values)


# --- writing CDR directly ------------------------------------------------------------------------

U32 = struct.Struct("<I")
CDR_LE = b"\x00\x01\x00\x00"
POSE_ITEM = np.dtype((np.void, 56))  # geometry_msgs/Pose or Transform: 7 float64, as one item


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

    def count(self, field: str, item_size: int) -> int:
        """A sequence length, refused before anything is allocated if its items cannot fit."""
        count = int(self.scalar("I", field))
        left = len(self.buffer) - self.offset
        if count * item_size > left:
            raise DecodeError(
                self.type_name, field, self.offset - 4, f"count {count} needs {count * item_size} bytes, {left} left"
            )
        return count

    def octets(self, field: str) -> memoryview:
        length = self.count(field, 1)
        start = self.take(length, 1, field)
        return self.buffer[start : start + length]
