"""The tree viewer's `viewer2_comms_t` envelope around a request's JSON, the response status codes
and the channel names (docs/PROTOCOLS.md section 2)."""

from __future__ import annotations

from typing import Any

import orjson

from viewer_bridge.errors import RequestRejected
from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS
from viewer_bridge.lcmcodec.codegen import Buffer

FORMAT = "treeviewer_json"
VERSION = (1, 0)

# Response status codes (docs/PROTOCOLS.md section 2).
OK = 0
MISSING_PATHS = 1
ERROR_UNKNOWN_FORMAT = -1
ERROR_UNKNOWN_FORMAT_VERSION = -2
ERROR_HANDLING_REQUEST = -3
ERROR_UNKNOWN_REQUEST_TYPE = -4

Request = dict[str, Any]


def request_channel(client_id: str) -> str:
    return f"DIRECTOR_TREE_VIEWER_REQUEST_<{client_id}>"


def response_channel(client_id: str) -> str:
    return f"DIRECTOR_TREE_VIEWER_RESPONSE_<{client_id}>"


def encode(payload: Request, utime: int = 0) -> bytes:
    """A request or response in its `viewer2_comms_t` envelope."""
    data = orjson.dumps(payload)  # compact; several times faster than json for float-heavy loads
    return envelope(data, int(utime or echo_time(payload)))


def envelope(data: bytes, utime: int) -> bytes:
    """JSON text already written, in its `viewer2_comms_t` envelope."""
    major, minor = VERSION
    return VIEWER2_COMMS.encode(
        VIEWER2_COMMS.message_class(
            utime=utime,
            format=FORMAT,
            format_version_major=major,
            format_version_minor=minor,
            num_bytes=len(data),
            data=data,
        )
    )


_ENVELOPE = VIEWER2_COMMS.type_name


def decode(data: Buffer) -> Request:
    """A `viewer2_comms_t` envelope's JSON object.

    Raises `DecodeError` for bytes that are no envelope, and `RequestRejected` (with the response
    status) for a wrong format or version, bad JSON, or JSON that is no object.
    """
    message = VIEWER2_COMMS.strict.decode(data)
    if message.format != FORMAT:
        raise RequestRejected(ERROR_UNKNOWN_FORMAT, f"{_ENVELOPE}.format: unknown format {message.format!r}")
    major, minor = message.format_version_major, message.format_version_minor
    if major != VERSION[0]:
        raise RequestRejected(
            ERROR_UNKNOWN_FORMAT_VERSION, f"{_ENVELOPE}.format_version_major: unknown version {major}.{minor}"
        )
    try:
        payload = orjson.loads(bytes(message.data))
    except orjson.JSONDecodeError as error:  # also raised for invalid UTF-8
        position = getattr(error, "pos", getattr(error, "start", 0))
        raise RequestRejected(
            ERROR_HANDLING_REQUEST, f"{_ENVELOPE}.data at character {position}: not JSON: {error}"
        ) from None
    if not isinstance(payload, dict):
        raise RequestRejected(ERROR_HANDLING_REQUEST, f"{_ENVELOPE}.data: the JSON is not an object")
    return payload


def request_timestamp(request: Request) -> Any:
    """The request's `timestamp` (or Director's `utime`) as sent, checked or not."""
    return request.get("timestamp", request.get("utime", 0))


def echo_time(request: Request) -> int:
    """The request's time, to echo in a reply, when it is one (an int64); else 0."""
    value = request_timestamp(request)
    valid = isinstance(value, int) and not isinstance(value, bool) and -(2**63) <= value < 2**63
    return value if valid else 0


__all__ = [
    "ERROR_HANDLING_REQUEST",
    "ERROR_UNKNOWN_FORMAT",
    "ERROR_UNKNOWN_FORMAT_VERSION",
    "ERROR_UNKNOWN_REQUEST_TYPE",
    "FORMAT",
    "MISSING_PATHS",
    "OK",
    "VERSION",
    "Request",
    "decode",
    "echo_time",
    "encode",
    "envelope",
    "request_channel",
    "request_timestamp",
    "response_channel",
]
