"""Drake's own traffic (tests/conftest.py's `drake_events`) through the generated codecs: every
role channel is there, and every message decodes as Drake's own classes decode it and is encoded
back to the same bytes."""

from __future__ import annotations

from collections import Counter
from typing import Any

from tests.optional import peer
from viewer_bridge.lcmcodec.codecs import codec_for
from viewer_bridge.transports.lcm import LcmEvent

# Drake's own lcm-gen classes, shipped with pydrake: imported by the tests that use them
drake_lcmtypes = peer("drake")


def values(message: Any) -> Any:
    """Every field of an lcm-gen (or our) message as plain lists, for comparing the two."""
    if hasattr(message, "__slots__") and not isinstance(message, (str, bytes)):
        return {name: values(getattr(message, name)) for name in message.__slots__}
    if isinstance(message, (list, tuple)):
        return [values(item) for item in message]
    return message


def test_drake_publishes_on_every_role_channel(drake_events: list[LcmEvent]) -> None:
    channels = Counter(event.channel for event in drake_events)
    for role in ("ILLUSTRATION", "PROXIMITY"):
        assert channels[f"DRAKE_VIEWER_LOAD_ROBOT_{role}"] >= 1
        assert channels[f"DRAKE_VIEWER_DRAW_{role}"] >= 3
        assert channels[f"DRAKE_VIEWER_DEFORMABLE_{role}"] >= 1


def test_every_message_decodes_like_drakes_classes_and_reencodes_to_the_same_bytes(
    drake_events: list[LcmEvent],
) -> None:
    assert len(drake_events) > 10
    for event in drake_events:
        codec = codec_for(event.data)
        assert codec is not None, event.channel
        ours = codec.decode(event.data)
        theirs = getattr(drake_lcmtypes, codec.definition.name).decode(event.data)
        assert values(ours) == values(theirs), event.channel
        assert codec.encode(ours) == event.data
