"""A timeline that clients may drive (play, pause, speed, seek), and the clock under it.

Nothing here knows a log format or a client protocol: a played log (`viewer_bridge.transports.
lcm_playback.LogPlayer`) is a `Timeline`, and a server whose clients have a timeline of their own
(Foxglove's playback bar) drives it through `request` and follows it through `watch`. A router
finds the timeline it plays, if any, in its `Shared` (`shared.given(Timelines).timeline`).
"""

from __future__ import annotations

import enum
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol


class Status(enum.Enum):
    PLAYING = "playing"
    PAUSED = "paused"
    ENDED = "ended"


@dataclass(frozen=True, slots=True)
class PlaybackState:
    """Where a timeline is: its status, its time (ns since the epoch), its speed; `did_seek` when
    a seek made this state, `request_id` the request it answers ("" for none)."""

    status: Status
    time_ns: int
    speed: float
    did_seek: bool = False
    request_id: str = ""


@dataclass(frozen=True, slots=True)
class PlaybackRequest:
    """What a client asks: play or pause, at `speed`, after a seek to `seek_ns` when it is not None."""

    play: bool
    speed: float
    seek_ns: int | None = None
    request_id: str = ""


@dataclass(frozen=True, slots=True)
class Answer:
    """A request's answer: the state after it, and what to tell the client when the request was
    refused or changed (a speed of 0, a seek past the end), else None."""

    state: PlaybackState
    note: str | None = None


class Timeline(Protocol):
    """What a server's clients drive: a range of time, played under a clock."""

    @property
    def range_ns(self) -> tuple[int, int]: ...

    def request(self, request: PlaybackRequest) -> Answer: ...

    def state(self) -> PlaybackState: ...

    def now_ns(self) -> int:
        """The clock's time, within the range."""

    def watch(self, on_state: Callable[[PlaybackState], None], on_time: Callable[[int], None]) -> None:
        """Call `on_state` when the state changes by itself (the end reached), `on_time` as the
        clock moves (a few times a second while playing, and after each seek)."""


class Timelines:
    """A router's slot for the timeline it plays (`Shared.given(Timelines)`): None unless a command
    that plays one (`viewer-bridge play`) gave the router one."""

    def __init__(self, timeline: Timeline | None = None) -> None:
        self.timeline = timeline


class PlaybackClock:
    """Log time against wall time: `now_us` moves at `speed` while playing, stands still while
    paused; each change re-anchors it at the log time it had then (or the one sought)."""

    def __init__(self, at_us: int, speed: float = 1.0, playing: bool = True) -> None:
        self._lock = threading.Lock()
        self._anchor_us = at_us
        self._anchor_wall = time.monotonic()
        self.speed = speed
        self.playing = playing

    def now_us(self) -> int:
        with self._lock:
            return self._now_us(time.monotonic())

    def _now_us(self, wall: float) -> int:
        if not self.playing:
            return self._anchor_us
        return self._anchor_us + round((wall - self._anchor_wall) * 1e6 * self.speed)

    def seconds_until(self, utime: int) -> float | None:
        """Wall seconds until the log time `utime` comes (<= 0: it has), or None while paused."""
        with self._lock:
            if not self.playing:
                return None
            return (utime - self._now_us(time.monotonic())) / 1e6 / self.speed

    def set(
        self, *, playing: bool | None = None, speed: float | None = None, at_us: int | None = None
    ) -> None:
        with self._lock:
            wall = time.monotonic()
            self._anchor_us = self._now_us(wall) if at_us is None else at_us
            self._anchor_wall = wall
            if playing is not None:
                self.playing = playing
            if speed is not None:
                self.speed = speed
