"""LCM as a transport: live buses (any LCM URL) and log files. Bytes in, bytes out.

Nothing here knows a message format; callers get `(channel, data, timestamp)` events.
`LcmTransport` is the router's view of it: a bus or a replayed log behind the `Transport`
interface, with one LCM subscription for every route (LCM channels carry any type).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import re
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import lcm

from viewer_bridge.errors import LogError, TransportUnavailable
from viewer_bridge.shared import Shared
from viewer_bridge.transports import base
from viewer_bridge.transports.lcm_playback import LogPlayer
from viewer_bridge.transports.lcm_url import log_to_write
from viewer_bridge.transports.playback import Timelines
from viewer_bridge.util.channels import MAX_CHANNELS, ChannelPattern
from viewer_bridge.util.hints import first_time

_log = logging.getLogger("viewer_bridge")
# LCM's default (ttl=0 never leaves the host), or LCM_DEFAULT_URL as LCM's own tools read it, so
# that the bridge, lcm-logger and a pydrake DrakeLcm() agree on one bus.
DEFAULT_URL = os.environ.get("LCM_DEFAULT_URL") or "udpm://239.255.76.67:7667?ttl=0"


@dataclass(frozen=True, slots=True)
class LcmEvent:
    channel: str
    data: bytes
    timestamp_us: int  # the log's receive time, or the local receive time when live


_SYNC = bytes.fromhex("eda1da01")  # every LCM log event starts with this word


def read_log(path: str | Path, channel: str = ".*") -> Iterator[LcmEvent]:
    """Every event of an LCM log file whose channel fully matches the regex `channel`.

    Raises `LogError` for a file that does not start like an LCM log. A log that ends in a partial
    event (a logger killed mid-write) yields every whole event and warns with the byte offset.
    """
    pattern = re.compile(channel)
    with open(path, "rb") as file:
        start = file.read(len(_SYNC))
    if start and start != _SYNC:
        raise LogError(
            f"{path} is not an LCM log: it starts with {start.hex()}, not the event sync word {_SYNC.hex()}"
        )
    log = lcm.EventLog(str(path), "r")
    whole = 0  # where the last whole event ends
    try:
        while (event := log.read_next_event()) is not None:
            whole = log.tell()
            if pattern.fullmatch(event.channel):
                yield LcmEvent(event.channel, bytes(event.data), event.timestamp)
        if whole < log.size():
            _log.warning(
                "%s ends in a partial event: the %d bytes after byte %d are not a whole event and were skipped",
                path,
                log.size() - whole,
                whole,
            )
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


def _open(url: str) -> lcm.LCM:
    """An LCM instance on `url`; a URL LCM cannot open is a `TransportUnavailable` that names it."""
    try:
        return lcm.LCM(url)
    except RuntimeError as error:  # LCM says only "Couldn't create LCM"
        raise TransportUnavailable(
            f"LCM cannot open {url} ({error}): is it an LCM URL, e.g. {DEFAULT_URL}?"
        ) from None


class Subscription:
    """Events received live on `url` whose channel matches the regex `channel`.

    Subscribed as soon as it is made (so nothing published after that is missed); iterate it to
    receive, until `duration` seconds after the iteration starts, or forever when it is None.
    """

    def __init__(self, url: str, channel: str = ".*") -> None:
        self._bus = _open(url)
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
        self._bus = _open(url)

    def publish(self, channel: str, data: bytes) -> None:
        self._bus.publish(channel, data)


Callback = Callable[[str, bytes, int], None]  # channel, data, receive time (time.time_ns() // 1000)


RECEIVE_BUFFER = 16 * 1024 * 1024  # ~0.25 s of 1000-link draws at 1 kHz, held while the bridge is busy
_RMEM_MAX = Path("/proc/sys/net/core/rmem_max")


def with_receive_buffer(url: str, wanted: int = RECEIVE_BUFFER) -> str:
    """A udpm URL that asks for a large socket receive buffer, unless it names its own.

    The kernel's default (about 200 kB) holds three 1000-link draws: a burst, or a moment of a
    busy core, and the kernel drops datagrams before LCM sees them. The request is capped at
    `net.core.rmem_max`, the most the kernel grants (LCM would warn on every start otherwise);
    when that is less than `wanted`, this says how to raise it, once per machine (`util/hints.py`).
    """
    if not url.startswith("udpm://") or "recv_buf_size=" in url:
        return url
    return f"{url}{'&' if '?' in url else '?'}recv_buf_size={_granted(wanted)}"


@functools.cache  # once per process: the advice is logged once
def _granted(wanted: int) -> int:
    try:
        allowed = int(_RMEM_MAX.read_text())
    except (OSError, ValueError):
        return wanted
    if allowed < wanted and first_time("rmem_max"):  # once per machine (or under --debug)
        _log.info(
            "LCM receive buffer: %d kB asked, the kernel allows %d kB (net.core.rmem_max); for fewer "
            "drops under load: sudo sysctl -w net.core.rmem_max=%d",
            wanted // 1024,
            allowed // 1024,
            wanted,
        )
    return min(allowed, wanted)


def kernel_drops(port: int) -> int | None:
    """Datagrams the kernel dropped for this process's UDP sockets on `port` (full buffers); None
    when they cannot be read now (no file to read them with: the process is out of files).

    Read from /proc/net/udp (its last column), for the sockets among this process's files.
    """
    inodes = set()
    try:
        links = list(Path("/proc/self/fd").iterdir())
    except OSError:  # EMFILE: listing a directory takes a file
        return None
    for link in links:
        with contextlib.suppress(OSError):
            target = os.readlink(link)
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    drops = 0
    try:
        for line in Path("/proc/net/udp").read_text().splitlines()[1:]:
            fields = line.split()
            if int(fields[1].rsplit(":", 1)[1], 16) == port and fields[9] in inodes:
                drops += int(fields[-1])
    except OSError:
        return None
    return drops


def _udpm_port(url: str) -> int | None:
    match = re.match(r"udpm://[^:/?]+:(\d+)", url)
    return int(match.group(1)) if match else None


class LcmBus:
    """A live LCM bus (any URL: udpm, memq, ...) driven by a thread of its own.

    `subscribe(regex, callback)` calls back on that thread, with the receive time in
    microseconds; callbacks must be quick (hand the bytes over and return). A udpm bus asks for
    a large receive buffer (`with_receive_buffer`) and counts what the kernel dropped anyway.
    """

    def __init__(self, url: str = DEFAULT_URL) -> None:
        self.url = url
        self._lcm = _open(with_receive_buffer(url))
        self._port = _udpm_port(url)
        self._drops = 0  # the last count of kernel_drops read
        # Read once per message: a plain attribute, not an Event (whose `is_set` is a Python call).
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name=f"lcm {url}", daemon=True)

    def kernel_drops(self) -> int:
        """Datagrams the kernel dropped before LCM read them (0 for other providers); the last
        count read while they cannot be read (out of files: a report never fails for it)."""
        if self._port is None:
            return 0
        drops = kernel_drops(self._port)
        if drops is not None:
            self._drops = drops
        return self._drops

    def subscribe(self, channel: str, callback: Callback) -> None:
        subscription = self._lcm.subscribe(
            channel, lambda name, data: callback(name, data, time.time_ns() // 1000)
        )
        # LCM queues at most 30 messages per subscription while a callback runs, and discards the
        # rest without a word. Unbounded here: loss happens only where it is counted (the kernel's
        # socket buffer, a route's mailbox); the router keeps the callback quick (`InlineBudget`).
        subscription.set_queue_capacity(0)

    def subscribe_bytes(self, channel: str, handler: Callable[[str, bytes], None]) -> None:
        """As `subscribe`, the handler called by LCM itself with (channel, data): no call in
        between, no clock read (the handler reads it when it needs it)."""
        self._lcm.subscribe(channel, handler).set_queue_capacity(0)  # as `subscribe`'s

    def publish(self, channel: str, data: bytes) -> None:
        self._lcm.publish(channel, data)

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        handle_timeout = self._lcm.handle_timeout
        while not self._stopping:
            handle_timeout(100)

    def close(self) -> None:
        self._stopping = True
        if self._thread.is_alive():
            self._thread.join(timeout=2)


class LogReplay:
    """An LCM log played back as if live: same interface as `LcmBus` for subscribers.

    `speed` 1.0 keeps the recorded timing, 2.0 plays twice as fast, 0 as fast as possible.
    Publishing goes nowhere (a log is read-only). `finished` is set at the end of the log.
    """

    def __init__(self, path: str | Path, speed: float = 1.0) -> None:
        self.url = f"file://{path}"
        self.path = Path(path)
        self.speed = speed
        self.finished = threading.Event()
        self._subscribers: list[tuple[re.Pattern[str], Callback]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"replay {path}", daemon=True)

    def subscribe(self, channel: str, callback: Callback) -> None:
        self._subscribers.append((re.compile(channel), callback))

    def publish(self, channel: str, data: bytes) -> None:
        raise OSError(f"cannot publish on {channel}: {self.url} is a log being replayed")

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        started = time.monotonic()
        first: int | None = None
        try:
            for event in read_log(self.path):
                if self._stop.is_set():
                    return
                first = event.timestamp_us if first is None else first
                if self.speed > 0:
                    due = started + (event.timestamp_us - first) / 1e6 / self.speed
                    if self._stop.wait(max(0.0, due - time.monotonic())):
                        return
                for pattern, callback in self._subscribers:
                    if pattern.fullmatch(event.channel):
                        callback(event.channel, event.data, time.time_ns() // 1000)
        finally:
            self.finished.set()

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)


def _open_bus(url: str) -> LcmBus | LogReplay:
    """A live bus for an LCM URL; a replay for `file://PATH[?speed=S]` or a path to a log file.

    `file://PATH?mode=w` (or `a`) is a bus too: LCM writes what is published on it into PATH."""
    if log_to_write(url) is not None:
        return LcmBus(url)
    if url.startswith("file://") or (("://" not in url) and Path(url.split("?")[0]).is_file()):
        path, _, query = url.removeprefix("file://").partition("?")
        speed = 1.0
        for part in filter(None, query.split("&")):
            key, _, value = part.partition("=")
            if key == "mode" and value == "r":
                continue
            if key != "speed":
                raise TransportUnavailable(f"{url}: unknown log option {key!r} (known: speed, mode=r|w|a)")
            try:
                speed = float(value)
            except ValueError:
                raise TransportUnavailable(f"{url}: speed={value!r} is not a number") from None
        if not Path(path).is_file():
            raise TransportUnavailable(f"{url}: no such log file")
        return LogReplay(path, speed)
    return LcmBus(url)


# The patterns LCM's C library (POSIX extended regular expressions) reads as Python does: plain
# characters, groups ((?:...) read as (...)), alternation, ., [sets] and greedy ?, * and +; no
# other (?...), no \\ escapes, {n,m} or lazy quantifiers.
_POSIX_ALIKE = re.compile(r"[A-Za-z0-9_<>/. ()|?*+\[\]^$-]*")
_NOT_POSIX = re.compile(r"\(\?|[?*+]\?")


def lcm_filter(patterns: list[str]) -> str:
    """The channel regex the bus subscribes with: any of `patterns`, when LCM's C library reads each
    as Python does, else `.*`. LCM's receiving thread drops a channel no subscription matches
    before Python wakes for it, so a process reads in Python only its routes' channels (a worker
    beside others on the same bus, most of all); the router still matches each route's pattern."""
    posix = sorted({pattern.replace("(?:", "(") for pattern in patterns})  # a group either way
    if not posix or any(not _POSIX_ALIKE.fullmatch(p) or _NOT_POSIX.search(p) for p in posix):
        return ".*"
    return "(" + "|".join(f"({pattern})" for pattern in posix) + ")"


class LcmSettings(base.TransportSettings):
    url: str = DEFAULT_URL  # a live bus, or a log to replay: file://LOG?speed=S


class LcmTransport(base.Transport):
    """LCM for the router: every route's pattern is served by one subscription to everything,
    so a message several routes read is received (and decoded) once."""

    Settings = LcmSettings
    encodings = frozenset({base.LCM})
    several_processes = True  # multicast: every process gets its own copy of each message
    settings: LcmSettings

    def __init__(self, settings: LcmSettings, bus: LcmBus | LogReplay | LogPlayer | None = None) -> None:
        """`bus`: where the messages come from instead of `settings.url` (a log `play` plays)."""
        super().__init__(settings)
        self.bus = _open_bus(settings.url) if bus is None else bus
        self._routes: list[tuple[ChannelPattern, base.Deliver]] = []
        # The routes a channel goes to, found once per channel name: one dictionary lookup a
        # message. Bounded as a pattern's matches are: past that many names, matched each time.
        # With them, the express path's maker of the channel's one route, if it offers one.
        self._delivers: dict[str, tuple[tuple[base.Deliver, ...], base.ExpressFor | None]] = {}
        self._express_for: dict[base.Deliver, base.ExpressFor] = {}  # by the deliver it stands beside
        # A live bus's channels whose one route carries them on its express path (`offer_express`):
        # one dictionary lookup and that call a message, no `Received` made. Bounded as `_delivers`.
        self._express: dict[str, base.Express] = {}

    @classmethod
    def create(cls, settings: base.TransportSettings, shared: Shared) -> LcmTransport:
        assert isinstance(settings, LcmSettings)
        played = shared.given(Timelines).timeline  # `viewer-bridge play`: the log it plays is the bus
        return cls(settings, played if isinstance(played, LogPlayer) else None)

    def subscribe(
        self, pattern: str, message_type: base.MessageType, qos: base.Qos, deliver: base.Deliver
    ) -> None:
        self._routes.append((ChannelPattern(pattern), deliver))
        self._delivers.clear()
        self._express.clear()

    def offer_express(self, deliver: base.Deliver, express_for: base.ExpressFor) -> None:
        self._express_for[deliver] = express_for
        self._delivers.clear()
        self._express.clear()

    def publisher(self, name: str, message_type: base.MessageType, qos: base.Qos) -> base.Publisher:
        bus = self.bus
        return base.ClosingPublisher(lambda data: bus.publish(name, data))  # it holds nothing

    def start(self) -> None:
        channels = lcm_filter([pattern.pattern.pattern for pattern, _ in self._routes])
        if isinstance(self.bus, LcmBus):  # live: each message tries its route's express path first
            self.bus.subscribe_bytes(channels, self._on_message)
        else:
            self.bus.subscribe(channels, self._dispatch)
        self.bus.start()

    def _on_message(self, channel: str, data: bytes) -> None:
        """LCM's handler on a live bus: the channel's express path when it has one and takes the
        message, else every matching route as usual."""
        express = self._express.get(channel)
        if express is not None and express(data):
            return
        self._dispatch(channel, data, time.time_ns() // 1000)

    def _dispatch(self, channel: str, data: bytes, received_us: int) -> None:
        found = self._delivers.get(channel)
        if found is None:
            delivers = tuple(deliver for pattern, deliver in self._routes if pattern.fullmatch(channel))
            found = (delivers, self._express_for.get(delivers[0]) if len(delivers) == 1 else None)
            if len(self._delivers) < MAX_CHANNELS:
                self._delivers[channel] = found
        delivers, express_for = found
        if delivers:
            message = base.Received(channel, data, received_us)
            for deliver in delivers:
                deliver(message)
        if express_for is not None:  # after the full path: whether the route has one now
            express = express_for(channel)
            if express is None:
                self._express.pop(channel, None)
            elif len(self._express) < MAX_CHANNELS:
                self._express[channel] = express

    def describe(self) -> str:
        return f"LCM {self.bus.url}{' (played)' if isinstance(self.bus, LogPlayer) else ''}"

    def errors(self) -> dict[str, int]:
        drops = self.bus.kernel_drops() if isinstance(self.bus, LcmBus) else 0
        return {"dropped_by_kernel": drops} if drops else {}

    def finished(self) -> bool:
        return isinstance(self.bus, LogReplay | LogPlayer) and self.bus.finished.is_set()

    def close(self) -> None:
        self.bus.close()


__all__ = [
    "Callback",
    "DEFAULT_URL",
    "LcmBus",
    "LcmEvent",
    "LcmSettings",
    "LcmTransport",
    "LogReplay",
    "Publisher",
    "RECEIVE_BUFFER",
    "Subscription",
    "kernel_drops",
    "read_log",
    "with_receive_buffer",
    "write_log",
]
