"""Messages as plain values, compared within float round-off: for outputs whose last bits vary.

Poses composed from floats differ in their last bits from one machine to another (the BLAS kernel
picked for the CPU, FMA or not, the order of a sum), so a test of such output compares what the
bytes mean: every string, integer, enum and length exactly, every float within a few float32
ulps. The readers here are the peers' own (rosbags for CDR, protoc's classes for protobuf, the
LCM codec and a JSON parser for Director's envelopes), not the bridge's decoders.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Any

import numpy as np
import orjson
from google.protobuf.descriptor import FieldDescriptor
from google.protobuf.message import Message

# Four float32 ulps at 1, relative: Drake's draws are float32, so nothing finer means anything.
RTOL = 2.0**-21
ATOL = 1e-12  # for values that cancel to about zero (1 - 1e-16 against 1 - 2e-16 and such)


def plain(value: Any) -> Any:
    """A decoded message (protobuf, a rosbags dataclass, parsed JSON) as dicts, lists and scalars.

    Protobuf scalars are read whether set or not: proto3 leaves out a 0.0 that another machine
    may write as 1e-17.
    """
    if isinstance(value, Message):
        return {field.name: plain(_field(value, field)) for field in value.DESCRIPTOR.fields}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {field.name: plain(getattr(value, field.name)) for field in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {key: plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)) or (hasattr(value, "__len__") and hasattr(value, "append")):
        return [plain(item) for item in value]  # also protobuf's repeated containers
    if isinstance(value, np.ndarray):
        return value.astype(np.float64) if value.dtype.kind == "f" else value.tolist()
    return value


def renamed(value: Any, old: str, new: str) -> Any:
    """A plain value with `old` replaced by `new` in every string (a folder named in the output)."""
    if isinstance(value, str):
        return value.replace(old, new)
    if isinstance(value, dict):
        return {key: renamed(item, old, new) for key, item in value.items()}
    if isinstance(value, list):
        return [renamed(item, old, new) for item in value]
    return value


def _field(message: Message, field: FieldDescriptor) -> Any:
    if (
        field.type == FieldDescriptor.TYPE_MESSAGE
        and not field.is_repeated
        and not message.HasField(field.name)
    ):
        return None
    return getattr(message, field.name)


def differences(actual: Any, expected: Any, atol: float = ATOL, where: str = "") -> Iterator[str]:
    """Where two plain values differ beyond round-off: floats within `atol` + `RTOL` x magnitude."""
    if isinstance(expected, float) and isinstance(actual, (float, int)) and not isinstance(actual, bool):
        if not _close(np.float64(actual), np.float64(expected), atol):
            yield f"{where}: {actual!r} != {expected!r}"
    elif isinstance(expected, np.ndarray) or isinstance(actual, np.ndarray):
        a, e = np.asarray(actual, dtype=np.float64), np.asarray(expected, dtype=np.float64)
        if a.shape != e.shape:
            yield f"{where}: shape {a.shape} != {e.shape}"
        elif not _close(a, e, atol).all():
            yield f"{where}[{int(np.flatnonzero(~_close(a, e, atol))[0])}]: beyond round-off"
    elif isinstance(expected, dict) and isinstance(actual, dict):
        if actual.keys() != expected.keys():
            yield f"{where}: keys {sorted(actual)} != {sorted(expected)}"
        for key in expected.keys() & actual.keys():
            yield from differences(actual[key], expected[key], atol, f"{where}.{key}")
    elif isinstance(expected, list) and isinstance(actual, list):
        if len(actual) != len(expected):
            yield f"{where}: length {len(actual)} != {len(expected)}"
        for index, (a, e) in enumerate(zip(actual, expected, strict=False)):
            yield from differences(a, e, atol, f"{where}[{index}]")
    elif actual != expected or type(actual) is not type(expected):
        yield f"{where}: {actual!r} != {expected!r}"


def _close(actual: Any, expected: Any, atol: float) -> Any:
    both_nan = np.isnan(actual) & np.isnan(expected)
    return both_nan | (
        np.abs(actual - expected) <= atol + RTOL * np.maximum(np.abs(actual), np.abs(expected))
    )


def json_envelope(data: bytes) -> Any:
    """A Director `viewer2_comms_t` request: its header fields and its parsed JSON."""
    from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS

    message = VIEWER2_COMMS.decode(data)
    names = ("utime", "format", "format_version_major", "format_version_minor")  # num_bytes: the text's
    fields = {name: getattr(message, name) for name in names}
    return {**fields, "data": orjson.loads(message.data)}
