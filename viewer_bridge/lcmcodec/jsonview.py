"""Any decoded LCM message as plain JSON-ready values, for `viewer-bridge dump`.

Numbers, strings and booleans stay themselves, nested structs become objects and arrays lists
(nested for multi-dimensional ones). A byte array (an image's pixels, a blob) is summarised as
its size and a CRC-32 unless the whole content is asked for, then it is text when it is UTF-8 (the
tree viewer's JSON is) or base64.
"""

from __future__ import annotations

import base64
import zlib
from typing import Any

from viewer_bridge.lcmcodec.serde import LcmMessage

__all__ = ["json_ready", "message_json"]


def message_json(message: LcmMessage, *, bytes_summary: bool = True) -> dict[str, object]:
    """Every field of `message`, JSON-ready."""
    return {name: json_ready(getattr(message, name), bytes_summary) for name in message.field_names()}


def json_ready(value: Any, bytes_summary: bool = True) -> Any:
    """One decoded value (a message, a list, bytes, a number ...), JSON-ready."""
    if isinstance(value, LcmMessage):
        return message_json(value, bytes_summary=bytes_summary)
    if isinstance(value, list | tuple):
        return [json_ready(item, bytes_summary) for item in value]
    if isinstance(value, bytes | bytearray):
        return _bytes(bytes(value), bytes_summary)
    return value


def _bytes(value: bytes, summary: bool) -> dict[str, object]:
    if summary:
        return {"bytes": len(value), "crc32": f"{zlib.crc32(value):08x}"}
    try:
        return {"utf8": value.decode("utf-8")}
    except UnicodeDecodeError:
        return {"base64": base64.b64encode(value).decode("ascii")}
