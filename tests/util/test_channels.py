"""A channel pattern matched once per name (viewer_bridge/util/channels.py)."""

from __future__ import annotations

import pytest

from viewer_bridge.util import channels
from viewer_bridge.util.channels import ChannelPattern


def test_a_channel_is_matched_once_and_answers_as_the_regex_does() -> None:
    pattern = ChannelPattern("(?!SELF$)(IIWA_.*)")
    first = pattern.fullmatch("IIWA_STATUS")
    assert first is not None and first.groups() == ("IIWA_STATUS",)
    assert pattern.fullmatch("IIWA_STATUS") is first  # the same match, not matched again
    assert pattern.fullmatch("SELF") is None and pattern.fullmatch("SELF") is None
    assert pattern.fullmatch("IIWA_STATUS\n") is None  # a full match, as re's fullmatch


def test_a_flood_of_names_is_matched_each_time_past_the_bound(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(channels, "MAX_CHANNELS", 3)
    pattern = ChannelPattern("(.*)")
    for index in range(100):
        match = pattern.fullmatch(f"C{index}")
        assert match is not None and match.group(1) == f"C{index}"
    assert pattern.remembered == 3  # memory never grows with the names
