"""A channel pattern matched once per channel name, not once per message.

A bus repeats a few names at high rates (20 channels at 10 kHz between them), and a regex match
costs as much as the rest of relaying a small message. A match is immutable, so the one of a
channel's first message serves every later message on it. Bounded: past `MAX_CHANNELS` names (a
flood of new names from a hostile peer) the rest are matched each time, and memory never grows.
"""

from __future__ import annotations

import re

MAX_CHANNELS = 4096  # names whose match is kept, per pattern

_UNSEEN = object()


class ChannelPattern:
    """`re.Pattern.fullmatch` on channel names, remembered per name. Shared by threads: a dict
    store is atomic, and two that race on a new name both match it, to the same result."""

    __slots__ = ("pattern", "_matches")

    def __init__(self, pattern: str) -> None:
        self.pattern = re.compile(pattern)
        self._matches: dict[str, re.Match[str] | None] = {}

    @property
    def remembered(self) -> int:
        """How many names' matches are kept (at most MAX_CHANNELS)."""
        return len(self._matches)

    def fullmatch(self, channel: str) -> re.Match[str] | None:
        match = self._matches.get(channel, _UNSEEN)
        if match is _UNSEEN:
            match = self.pattern.fullmatch(channel)
            if len(self._matches) < MAX_CHANNELS:
                self._matches[channel] = match
        return match  # type: ignore[return-value]
