"""Render LCM events of any known type as readable text or as one JSON object per message.

The types are a `TypeLibrary`'s (the project's, Drake's and whatever `--lcm-types` names). JSON
carries a byte array whole, as `{"utf8": text}` or `{"base64": ...}` (what `from_json` and the type
store's `from_dict` take back); text shows it as its size and CRC-32 (`bytes_summary`).
JSON has no NaN or infinity: such a float is written as the string "NaN", "Infinity" or
"-Infinity" (the words JavaScript and Python's own parser use), so that every line is valid JSON.
"""

from __future__ import annotations

import json
import math
from functools import cache
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.transports.lcm import LcmEvent


@cache
def default_library() -> TypeLibrary:
    """The project's types and, when pydrake is installed, Drake's."""
    return TypeLibrary.load()


def describe(
    event: LcmEvent, library: TypeLibrary | None = None, *, bytes_summary: bool = True
) -> dict[str, Any]:
    """A JSON-ready description of one event: its type and every decoded field, or the error."""
    library = library or default_library()
    record: dict[str, Any] = {
        "channel": event.channel,
        "timestamp_us": event.timestamp_us,
        "size": len(event.data),
        "fingerprint": event.data[:8].hex(),
    }
    known = library.for_data(event.data, event.channel)
    if known is None:
        record["type"] = None
        record["error"] = "no known LCM type has this fingerprint"
        return record
    record["type"] = known.full_name
    try:
        record["message"] = known.to_dict(event.data, bytes_summary=bytes_summary)
    except DecodeError as error:
        record["error"] = str(error)
    return record


def as_json(event: LcmEvent, library: TypeLibrary | None = None, *, bytes_summary: bool = False) -> str:
    """One line of valid JSON: channel, time, size, fingerprint, type and message (or error);
    a NaN or infinite float as a string ("NaN", "Infinity", "-Infinity"), byte arrays whole."""
    record = describe(event, library, bytes_summary=bytes_summary)
    try:  # almost every message is finite: the walk that replaces non-finite floats is the exception
        return json.dumps(record, separators=(",", ":"), allow_nan=False)
    except ValueError:
        return json.dumps(_finite_json(record), separators=(",", ":"), allow_nan=False)


def _finite_json(value: Any) -> Any:
    """`value` with every NaN or infinite float (at any depth) replaced by its name as a string."""
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else "Infinity" if value > 0 else "-Infinity"
    if isinstance(value, dict):
        return {key: _finite_json(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_finite_json(item) for item in value]
    return value


def as_text(event: LcmEvent, library: TypeLibrary | None = None, *, bytes_summary: bool = True) -> str:
    """A header line, then one indented line per field."""
    record = describe(event, library, bytes_summary=bytes_summary)
    seconds = record["timestamp_us"] / 1e6
    header = (
        f"[{seconds:.6f}] {record['channel']} {record['type'] or '(unknown type)'} ({record['size']} bytes)"
    )
    lines = [header]
    if "error" in record:
        lines.append(f"  error: {record['error']}")
    else:
        _text_lines(record["message"], 1, lines)
    return "\n".join(lines)


def _text_lines(value: dict[str, Any], depth: int, lines: list[str]) -> None:
    pad = "  " * depth
    for key, item in value.items():
        if isinstance(item, list) and item and isinstance(item[0], dict):
            for index, child in enumerate(item):
                lines.append(f"{pad}{key}[{index}]:")
                _text_lines(child, depth + 1, lines)
        elif isinstance(item, dict) and ("utf8" in item or "base64" in item):
            kind, text = next(iter(item.items()))
            lines.append(f"{pad}{key} ({kind}): {text}")
        elif isinstance(item, dict) and set(item) == {"bytes", "crc32"}:
            lines.append(f"{pad}{key}: {item['bytes']} bytes, CRC-32 {item['crc32']}")
        elif isinstance(item, dict):
            lines.append(f"{pad}{key}:")
            _text_lines(item, depth + 1, lines)
        else:
            lines.append(f"{pad}{key}: {_short(item)}")


def _short(value: Any) -> str:
    """repr, but a float that is exactly a float32 (most of LCM's) is shown as float32 prints it."""
    if isinstance(value, list):
        return "[" + ", ".join(_short(item) for item in value) + "]"
    if isinstance(value, float) and math.isfinite(value) and float(np.float32(value)) == value:
        return str(np.float32(value))
    return repr(value)
