"""The tree viewer's envelope: what is refused, with which response status, and the channels."""

from __future__ import annotations

import pytest

from viewer_bridge.errors import DecodeError, RequestRejected
from viewer_bridge.formats.tree_viewer.envelope import (
    ERROR_HANDLING_REQUEST,
    ERROR_UNKNOWN_FORMAT,
    ERROR_UNKNOWN_FORMAT_VERSION,
    FORMAT,
    decode,
    request_channel,
)
from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS


def envelope(format_name: str = FORMAT, major: int = 1, data: bytes = b"{}") -> bytes:
    return VIEWER2_COMMS.encode(
        VIEWER2_COMMS.message_class(
            utime=1, format=format_name, format_version_major=major, format_version_minor=0,
            num_bytes=len(data), data=data,
        )
    )  # fmt: skip


@pytest.mark.parametrize(
    ("data", "status", "reason"),
    [
        (envelope("msgpack"), ERROR_UNKNOWN_FORMAT, "unknown format 'msgpack'"),
        (envelope(major=2), ERROR_UNKNOWN_FORMAT_VERSION, "unknown version 2.0"),
        (envelope(data=b'{"setgeometry": ['), ERROR_HANDLING_REQUEST, "not JSON"),
        (envelope(data=b"[1, 2]"), ERROR_HANDLING_REQUEST, "not an object"),
    ],
)
def test_bad_envelopes_carry_the_response_status(data: bytes, status: int, reason: str) -> None:
    with pytest.raises(RequestRejected, match=reason) as caught:
        decode(data)
    assert caught.value.status == status


def test_truncated_envelope_is_a_decode_error() -> None:
    with pytest.raises(DecodeError, match="robotlocomotion.viewer2_comms_t"):
        decode(envelope()[:-1])
    assert request_channel("abc") == "DIRECTOR_TREE_VIEWER_REQUEST_<abc>"
