"""Render LCM events as readable text or as one JSON object per message, with every field."""

from __future__ import annotations

import base64
import json
import math
from functools import cache
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.transports.lcm import LcmEvent


@cache
def _project_types() -> TypeLibrary:
    return TypeLibrary.load(drake=False)


def describe(event: LcmEvent, types: TypeLibrary | None = None) -> dict[str, Any]:
    """A JSON-ready description of one event: its type (any of `types`; by default the
    project's own) and every decoded field, or the error."""
    types = _project_types() if types is None else types
    record: dict[str, Any] = {
        "channel": event.channel,
        "timestamp_us": event.timestamp_us,
        "size": len(event.data),
        "fingerprint": event.data[:8].hex(),
    }
    lcm_type = types.for_data(event.data)
    if lcm_type is None:
        record["type"] = None
        record["error"] = "no known LCM type has this fingerprint (--lcm-types adds types)"
        return record
    record["type"] = lcm_type.full_name
    try:
        record["message"] = _json_ready(lcm_type.to_json(event.data, bytes_summary=False))
    except DecodeError as error:
        record["error"] = str(error)
    return record


def _json_ready(value: Any) -> Any:
    if isinstance(value, dict):
        return {key: _json_ready(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_json_ready(item) for item in value]
    if isinstance(value, bytes):
        # A byte array is shown as text when it is UTF-8 (the tree viewer's JSON is), else base64.
        try:
            return {"utf8": value.decode("utf-8")}
        except UnicodeDecodeError:
            return {"base64": base64.b64encode(value).decode("ascii")}
    return value


def as_json(event: LcmEvent, types: TypeLibrary | None = None) -> str:
    return json.dumps(describe(event, types), separators=(",", ":"))


def as_text(event: LcmEvent, types: TypeLibrary | None = None) -> str:
    record = describe(event, types)
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


__all__ = [
    "as_json",
    "as_text",
    "describe",
]
