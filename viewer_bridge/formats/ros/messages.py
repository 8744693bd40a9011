"""ROS 2 messages as objects: build any Jazzy message, turn it into CDR or an rclpy object and back.

Messages are rosbags dataclasses (pure Python, every Jazzy type, CDR included), so everything
here works without a ROS installation; `to_rclpy` needs the ROS 2 message packages. The fast
paths write CDR directly instead (`viewer_bridge.formats.ros.cdr`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from functools import cache
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

from viewer_bridge.errors import DecodeError

STORE = get_typestore(Stores.ROS2_JAZZY)


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
    """The same message as an rclpy message object (needs the ROS 2 message packages: the `ros`
    extra's, whose absence is a `MissingExtra` naming the pip command)."""
    from viewer_bridge.util.extras import EXTRAS, missing

    package, _, name = message.__msgtype__.split("/")
    try:
        module = importlib.import_module(f"{package}.msg")
    except ImportError as error:
        if (error.name or "").partition(".")[0] in EXTRAS:  # a package of an extra (else: one built here)
            raise missing(error, "to_rclpy") from None
        raise
    cls = getattr(module, name)
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


__all__ = [
    "STORE",
    "from_cdr",
    "from_rclpy",
    "make",
    "to_cdr",
    "to_rclpy",
]
