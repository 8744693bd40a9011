"""An LCM log played under a clock that can pause, change speed and seek: the source of
`viewer-bridge play`, with the interface of a live bus (`viewer_bridge.transports.lcm.LcmBus`).

Events are delivered in time order when the clock reaches their time, received now (as a live
bus's, and as `run --lcm-url file://LOG` replays them: a ROS 2 tool's clock keeps moving forward
across seeks); a transport that shows the timeline stamps what it sends with `now_ns`. A seek re-sends the world
at the instant sought before playing on from it: per channel, the last event at or before it
(so the last load of each role, the last draw, the last of every other channel), found with two
binary searches per channel in the log's index (`LogIndex.latched`), however long the log. With
an `out` bus every event played (and re-sent) is published there too, as lcm-logplayer does; the
player never subscribes to that bus, so nothing it publishes comes back to the bridge.
"""

from __future__ import annotations

import logging
import math
import re
import threading
import time
from collections.abc import Callable
from typing import Protocol

import numpy as np

from viewer_bridge.transports.lcm_log_index import LoggedEvent, LogIndex
from viewer_bridge.transports.playback import Answer, PlaybackClock, PlaybackRequest, PlaybackState, Status

log = logging.getLogger("viewer_bridge")

Callback = Callable[[str, bytes, int], None]  # channel, data, receive time (time.time_ns() // 1000)
TICK_S = 0.1  # how often the clock's time is told while playing
BATCH = 256  # the most events taken at once when several are due (a seek still cuts in between two)


class LcmOut(Protocol):
    """What the player publishes on (`viewer_bridge.transports.lcm.Publisher`)."""

    def publish(self, channel: str, data: bytes) -> None: ...


class LogPlayer:
    """An indexed LCM log played from `start_us` (default its first time) at `speed`, paused or
    not, from its start again at the end when `loop`; a `Timeline` clients may drive."""

    def __init__(
        self,
        index: LogIndex,
        *,
        speed: float = 1.0,
        start_us: int | None = None,
        paused: bool = False,
        loop: bool = False,
        out: LcmOut | None = None,
    ) -> None:
        assert len(index) > 0, "an empty log has nothing to play"
        self.index = index
        self.url = f"file://{index.path}"
        self.loop = loop
        self.finished = threading.Event()  # set at the end when nobody can seek back (no watcher)
        self._out = out
        self._subscribers: list[tuple[re.Pattern[str], Callback]] = []
        self._watchers: list[tuple[Callable[[PlaybackState], None], Callable[[int], None]]] = []
        start = index.first_us if start_us is None else self._clamped(start_us)[0]
        self._clock = PlaybackClock(start, speed, playing=not paused)
        self._changed = threading.Condition()
        self._position = index.position(start)  # the next event to play
        self._resend = True  # the world at the clock's time goes first: at start and after each seek
        self._ended = False
        self._told_at = 0.0  # when the clock's time was last told (monotonic)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"play {index.path}", daemon=True)

    # -- the bus's interface (as LcmBus) --

    def subscribe(self, channel: str, callback: Callback) -> None:
        self._subscribers.append((re.compile(channel), callback))

    def publish(self, channel: str, data: bytes) -> None:
        if self._out is None:
            raise OSError(f"cannot publish on {channel}: {self.url} is a log being played (no --lcm-out)")
        self._out.publish(channel, data)

    def kernel_drops(self) -> int:
        return 0

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        with self._changed:
            self._changed.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=2)
        self.index.close()

    # -- the timeline's --

    @property
    def range_ns(self) -> tuple[int, int]:
        return self.index.first_us * 1000, self.index.last_us * 1000

    def now_ns(self) -> int:
        return self._time_us() * 1000

    def watch(self, on_state: Callable[[PlaybackState], None], on_time: Callable[[int], None]) -> None:
        self._watchers.append((on_state, on_time))

    def state(self, *, did_seek: bool = False, request_id: str = "") -> PlaybackState:
        clock = self._clock
        status = Status.ENDED if self._ended else Status.PLAYING if clock.playing else Status.PAUSED
        return PlaybackState(status, self._time_us() * 1000, clock.speed, did_seek, request_id)

    def request(self, request: PlaybackRequest, *, tell: bool = False) -> Answer:
        """Play or pause, at a speed, after a seek: applied at once (the thread re-sends the world
        at a seek's instant before it plays on). A speed that is not above 0 refuses the whole
        request; a seek outside the log is clamped to it. Each says why in the answer's note.
        `tell`: the new state goes to the watchers too (a request that came from none of them)."""
        if not (request.speed > 0 and math.isfinite(request.speed)):
            refusal = f"speed {request.speed:g} refused: a speed must be greater than 0 (playback unchanged)"
            return Answer(self.state(request_id=request.request_id), refusal)
        note = None
        with self._changed:
            at_us: int | None = None
            if request.seek_ns is not None:
                at_us, note = self._clamped(request.seek_ns // 1000)
                self._position = self.index.position(at_us)
                self._resend = True
                self._ended = False
            elif request.play and self._ended:  # play at the end: from the start again, as a player does
                at_us = self.index.first_us
                self._position = self.index.position(at_us)
                self._resend = True
                self._ended = False
            self._clock.set(playing=request.play, speed=request.speed, at_us=at_us)
            self._changed.notify_all()
            state = self.state(did_seek=at_us is not None, request_id=request.request_id)
        if tell:
            for on_state, _ in self._watchers:
                on_state(state)
        return Answer(state, note)

    def step(self, steps: int, channel: str) -> Answer:
        """Pause at the instant of the `steps`-th event on a channel fully matching the regex
        `channel` after the clock's time (before it when negative), the world there re-sent: one
        draw forward or back. At the first or last such event it stays there."""
        pattern = re.compile(channel)
        times = [self.index.utimes[events] for c, events in enumerate(self.index.by_channel)
                 if pattern.fullmatch(self.index.channels[c])]  # fmt: skip
        if not times:
            return Answer(self.state(), f"no channel matches {channel!r}: nothing to step to")
        instants = np.unique(np.concatenate(times))
        now = self._time_us()
        if steps > 0:
            at = int(np.searchsorted(instants, now, side="right")) + steps - 1
        else:
            at = int(np.searchsorted(instants, now, side="left")) + steps
        target = int(instants[min(max(at, 0), len(instants) - 1)])
        return self.request(
            PlaybackRequest(play=False, speed=self._clock.speed, seek_ns=target * 1000), tell=True
        )

    def _clamped(self, at_us: int) -> tuple[int, str | None]:
        first, last = self.index.first_us, self.index.last_us
        if first <= at_us <= last:
            return at_us, None
        clamped = min(max(at_us, first), last)
        return clamped, (
            f"seek to {at_us / 1e6:.6f} s is outside the log ({first / 1e6:.6f} to {last / 1e6:.6f} s): "
            f"clamped to {clamped / 1e6:.6f} s"
        )

    def _time_us(self) -> int:
        """The clock's time, within the log's range."""
        return min(max(self._clock.now_us(), self.index.first_us), self.index.last_us)

    # -- the player's thread --

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._changed:  # what to do is decided under the lock, done outside it
                latched = self._take_resend()
                due, ended = (range(0), None) if latched is not None else self._take_due()
            for event in latched or ():
                self._send(event)
            for position in due:
                if self._resend or self._stop.is_set():  # a seek meanwhile: what was due is no longer
                    break
                self._send(self.index.event(position))
            if latched is not None or ended is not None or self._clock.playing:
                self._tell_time(force=latched is not None or ended is not None)
            if ended is not None:  # after the time: the clock at the end, then "ended"
                for on_state, _ in self._watchers:
                    on_state(ended)

    def _take_resend(self) -> list[LoggedEvent] | None:
        """The world at the clock's time, when a seek (or the start) asks for it."""
        if not self._resend:
            return None
        self._resend = False
        return [self.index.event(position) for position in self.index.latched(self._position)]

    def _take_due(self) -> tuple[range, PlaybackState | None]:
        """The events whose time has come (at most `BATCH`: one lock taken for many), else a wait
        (for the next, a request, or a tick); and the state when the end was reached just now."""
        if self._position >= len(self.index):
            return range(0), self._at_end()
        wait = self._clock.seconds_until(int(self.index.utimes[self._position]))
        if wait is not None and wait <= 0:
            first = self._position
            if (
                self._position + 1 < len(self.index)
                and self.index.utimes[self._position + 1] <= self._clock.now_us()
            ):
                last = self.index.position(self._clock.now_us())
                self._position = min(last, first + BATCH)
            else:
                self._position = first + 1
            return range(first, self._position), None
        self._changed.wait(TICK_S if wait is None else min(wait, TICK_S))
        return range(0), None

    def _at_end(self) -> PlaybackState | None:
        """At the end: from the start again when looping; else ended (the state returned once),
        and finished when no client can seek back."""
        if self.loop and self._clock.playing:
            self._position = self.index.position(self.index.first_us)
            self._clock.set(at_us=self.index.first_us)
            self._resend = True
            return None
        if not self._ended and self._clock.now_us() >= self.index.last_us:
            self._ended = True
            self._clock.set(playing=False, at_us=self.index.last_us)
            if not self._watchers:
                self.finished.set()
            return self.state()
        self._changed.wait(TICK_S)
        return None

    def _tell_time(self, force: bool = False) -> None:
        """The clock's time to the watchers: after a seek or the end, and every `TICK_S` while playing."""
        now = time.monotonic()
        if not self._watchers or (not force and now - self._told_at < TICK_S):
            return
        self._told_at = now
        now_ns = self._time_us() * 1000
        for _, on_time in self._watchers:
            on_time(now_ns)

    def _send(self, event: LoggedEvent) -> None:
        if self._out is not None:
            try:
                self._out.publish(event.channel, event.data)
            except Exception as error:  # an out bus failing must not stop the playback
                log.warning("--lcm-out: %s: %s", event.channel, error)
        for pattern, callback in self._subscribers:
            if pattern.fullmatch(event.channel):
                callback(event.channel, event.data, time.time_ns() // 1000)
