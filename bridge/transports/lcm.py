"""LCM as a transport: live buses (any LCM URL) and log files. Bytes in, bytes out.

Nothing here knows a message format; callers get `(channel, data, timestamp)` events.
"""

from __future__ import annotations

import re
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import lcm

DEFAULT_URL = "udpm://239.255.76.67:7667?ttl=0"  # LCM's default; ttl=0 never leaves the host


@dataclass(frozen=True, slots=True)
class LcmEvent:
    channel: str
    data: bytes
    timestamp_us: int  # the log's receive time, or the local receive time when live


def read_log(path: str | Path, channel: str = ".*") -> Iterator[LcmEvent]:
    """Every event of an LCM log file whose channel fully matches the regex `channel`."""
    pattern = re.compile(channel)
    log = lcm.EventLog(str(path), "r")
    try:
        for event in log:
            if pattern.fullmatch(event.channel):
                yield LcmEvent(event.channel, bytes(event.data), event.timestamp)
    finally:
        log.close()


def write_log(path: str | Path, events: Iterator[LcmEvent] | list[LcmEvent]) -> int:
    """Write events to a new LCM log file; returns how many were written."""
    log = lcm.EventLog(str(path), "w", overwrite=True)
    count = 0
    try:
        for event in events:
            log.write_event(event.timestamp_us, event.channel, event.data)
            count += 1
    finally:
        log.close()
    return count


class Subscription:
    """Events received live on `url` whose channel matches the regex `channel`.

    Subscribed as soon as it is made (so nothing published after that is missed); iterate it to
    receive, until `duration` seconds after the iteration starts, or forever when it is None.
    """

    def __init__(self, url: str, channel: str = ".*") -> None:
        self._bus = lcm.LCM(url)
        self._received: deque[LcmEvent] = deque()
        self._subscription = self._bus.subscribe(channel, self._on_message)

    def _on_message(self, channel: str, data: bytes) -> None:
        self._received.append(LcmEvent(channel, bytes(data), time.time_ns() // 1000))

    def events(self, duration: float | None = None) -> Iterator[LcmEvent]:
        deadline = None if duration is None else time.monotonic() + duration
        try:
            while deadline is None or time.monotonic() < deadline:
                wait_s = 0.1 if deadline is None else min(0.1, deadline - time.monotonic())
                self._bus.handle_timeout(max(0, int(wait_s * 1000)))
                while self._received:
                    yield self._received.popleft()
        finally:
            self._bus.unsubscribe(self._subscription)


class Publisher:
    """Publishes bytes on an LCM URL."""

    def __init__(self, url: str = DEFAULT_URL) -> None:
        self._bus = lcm.LCM(url)

    def publish(self, channel: str, data: bytes) -> None:
        self._bus.publish(channel, data)
