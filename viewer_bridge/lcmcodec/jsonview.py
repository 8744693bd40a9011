"""Any decoded LCM message as plain JSON-ready values: the form `LcmType.from_dict` takes back.

A message is an object whose keys are its ROS 2 field names (`rosnames.field_names`); numbers,
strings and booleans stay themselves, a nested message is an object, and every array is one flat
list in row-major order, as the ROS 2 message holds it. A byte array (an image's pixels, a blob)
is summarised as its size and a CRC-32 unless the whole content is asked for, then it is
`{"utf8": text}` when it is UTF-8 (the tree viewer's JSON is) or `{"base64": ...}`.
"""

from __future__ import annotations

import base64
import zlib
from typing import Any

from viewer_bridge.lcmcodec.rosnames import field_names
from viewer_bridge.lcmcodec.schema import Member
from viewer_bridge.lcmcodec.serde import LcmMessage


def message_json(message: LcmMessage, *, bytes_summary: bool = True) -> dict[str, object]:
    """Every field of `message` under its JSON name, JSON-ready."""
    definition = message._codec.definition
    names = field_names(definition)
    return {
        names[member.name]: _member_json(getattr(message, member.name), member, bytes_summary)
        for member in definition.members
    }


def _member_json(value: Any, member: Member, summary: bool) -> Any:
    if member.type_name == "byte" and member.dims:  # the innermost dimension is one `bytes`
        rows = _flat(value, len(member.dims) - 1) if len(member.dims) > 1 else [value]
        return _bytes(b"".join(map(bytes, rows)), summary)
    if member.dims:
        return [_value_json(item, summary) for item in _flat(value, len(member.dims))]
    return _value_json(value, summary)


def _value_json(value: Any, summary: bool) -> Any:
    return message_json(value, bytes_summary=summary) if isinstance(value, LcmMessage) else value


def _flat(value: Any, depth: int) -> list[Any]:
    """The elements of `depth` levels of nested lists, in row-major order."""
    items = list(value)
    for _ in range(depth - 1):
        items = [item for row in items for item in row]
    return items


def _bytes(value: bytes, summary: bool) -> dict[str, object]:
    if summary:
        return {"bytes": len(value), "crc32": f"{zlib.crc32(value):08x}"}
    try:
        return {"utf8": value.decode("utf-8")}
    except UnicodeDecodeError:
        return {"base64": base64.b64encode(value).decode("ascii")}
