"""The router: runs each configured route's translator between transports.

The data path of one message:

    transport thread                     route worker thread
    ----------------                     -------------------
    Received --offer--> Mailbox ------>  lane (per stream) -> observe -> [lazy?] -> translate
    (one per message,   (per route,                                 -> publisher per output
     shared by routes)   bounded)

The router knows transports and translators only through their interfaces
(`bridge.transports.base.Transport`, `bridge.translators.base.Translator`) and their
registries: no transport or format is named here.

Threads: each transport delivers on a thread of its own. A route that is idle translates the
message right there, on the transport's thread (`InlineBudget`: no wake-up of another thread,
no GIL hand-off), as long as that thread is not too busy; otherwise the message goes to the
route's worker thread, which translates and publishes. Between the two sits a `Mailbox`,
bounded: with the `latest` policy it keeps the newest message per channel (a slow consumer
gets the newest draw, never a backlog; a draw never displaces a load, which is on another
channel), with `all` a FIFO of `qos.depth` that drops its oldest. Every drop, error and crash
is counted per route and kind; a translator that raises skips that message only.

A route has one translator per stream (a "lane"): per set of groups its source regex captures,
so the illustration and proximity streams a route matches never share a translator's state,
even when they publish on one topic (`/tf`). A lazy route that skipped messages while nobody
listened keeps the newest per channel and translates them the moment a subscriber appears, so
the subscriber gets the model and the latest poses at once, not at the next draw.
"""

from __future__ import annotations

import json
import logging
import math
import re
import threading
import time
import traceback
from collections import Counter, OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bridge.config import BridgeConfig, Route, destination_name
from bridge.errors import BridgeError
from bridge.skipped import collecting
from bridge.status import LogLines, StatusView
from bridge.translators import TRANSLATORS, LoadCache, Output, Translator
from bridge.transports import TRANSPORTS
from bridge.transports.base import Publisher, Qos, Received, Transport

log = logging.getLogger("viewer_bridge")


@dataclass(slots=True)
class Message:
    """A received message as one route saw it: with the match of the route's source pattern."""

    received: Received
    match: re.Match[str]

    @property
    def channel(self) -> str:
        return self.received.channel


class Mailbox:
    """Messages between a transport thread and a route's worker; never grows without bound."""

    def __init__(self, policy: str, depth: int, rate_limited: bool = False) -> None:
        self.keep_latest = policy == "latest"
        self._latest: OrderedDict[str, Message] = OrderedDict()
        self._fifo: deque[Message] = deque()
        self._depth = depth
        self._ready = threading.Condition()
        self.dropped = 0
        # With max_hz, a message superseded while the worker waits out the rate is skipped by
        # design: counted apart from drops (which say the bridge could not keep up).
        self._rate_limited = rate_limited
        self.rate_skipped = 0

    def put(self, message: Message) -> None:
        with self._ready:
            if self.keep_latest:
                if self._latest.pop(message.channel, None) is not None:
                    # superseded before it was translated
                    if self._rate_limited:
                        self.rate_skipped += 1
                    else:
                        self.dropped += 1
                self._latest[message.channel] = message
            else:
                if len(self._fifo) >= self._depth:
                    self._fifo.popleft()
                    self.dropped += 1
                self._fifo.append(message)
            self._ready.notify()

    def wait(self, timeout: float) -> bool:
        """Whether a message is waiting, within `timeout` seconds (without taking it)."""
        with self._ready:
            return bool(self._latest or self._fifo or self._ready.wait_for(self.__len__, timeout))

    def take(self) -> Message | None:
        """The next message, or None when there is none (never waits)."""
        with self._ready:
            if self._latest:
                return self._latest.popitem(last=False)[1]
            return self._fifo.popleft() if self._fifo else None

    def __len__(self) -> int:
        return len(self._latest) + len(self._fifo)


class InlineBudget:
    """Whether a transport's thread may translate a message itself instead of waking a worker.

    Handing a message to a route's worker costs a wake-up and a GIL hand-off between two threads
    per message, which on a loaded core costs more than a quick translation. So the thread that
    received a message translates it at once when the route is idle, as long as that thread has
    spent less than `share` of its recent time (decayed over `window_s`) translating inline.
    Past that, the workers take over: the mailbox's policy (the newest wins) applies again instead
    of a backlog building up in the transport's receive buffers.
    """

    def __init__(self, share: float = 0.5, window_s: float = 0.2) -> None:
        self._share_s = share * window_s
        self._window_s = window_s
        self._threads = threading.local()  # each receiving thread's own decayed busy time

    def _busy(self, now: float) -> float:
        state = self._threads
        busy: float = getattr(state, "busy", 0.0)
        if busy:
            busy *= math.exp((getattr(state, "at", now) - now) / self._window_s)
        return busy

    def allows(self) -> bool:
        return self._busy(time.perf_counter()) < self._share_s

    def spent(self, started: float, ended: float) -> None:
        self._threads.busy = self._busy(ended) + (ended - started)
        self._threads.at = ended


_SAMPLES = 4096  # latency and translate-time samples kept per route (a ring)


@dataclass
class RouteStats:
    messages_in: int = 0
    messages_out: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    idle_skipped: int = 0  # messages a lazy route did not translate: nobody was listening
    errors: Counter[str] = field(default_factory=Counter)
    warnings: Counter[str] = field(default_factory=Counter)  # e.g. a geometry skipped (bridge.skipped)
    translate_ms: deque[float] = field(default_factory=lambda: deque(maxlen=_SAMPLES))
    latency_ms: deque[float] = field(default_factory=lambda: deque(maxlen=_SAMPLES))

    def snapshot(self, dropped: int, queued: int, state: str, max_hz_skipped: int = 0) -> dict[str, Any]:
        return {
            "state": state,
            "messages_in": self.messages_in,
            "messages_out": self.messages_out,
            "bytes_in": self.bytes_in,
            "bytes_out": self.bytes_out,
            "idle_skipped": self.idle_skipped,
            "errors": dict(self.errors),
            "warnings": dict(self.warnings),
            "dropped": dropped,
            "max_hz_skipped": max_hz_skipped,  # superseded while a rate-limited route waited
            "queued": queued,
            "translate_ms": _percentiles(self.translate_ms),
            "latency_ms": _percentiles(self.latency_ms),
        }


def _percentiles(samples: deque[float]) -> dict[str, float | None]:
    if not samples:
        return {"p50": None, "p99": None, "max": None}
    values = np.fromiter(samples, dtype=np.float64)
    p50, p99 = np.percentile(values, [50, 99])
    return {"p50": round(float(p50), 4), "p99": round(float(p99), 4), "max": round(float(values.max()), 4)}


PublisherFor = Callable[[str, Output], Publisher]  # (full name, output) -> a publisher
_LISTENERS_CHECK_S = 0.25  # how often a lazy route asks its publishers whether anyone listens


class _Lane:
    """One stream of a route: its translator, the names it publishes on, what it skipped."""

    def __init__(
        self, name: str, translator: Translator, publisher: Callable[[str, Output], Publisher]
    ) -> None:
        self.name = name
        self.translator = translator
        self._publisher = publisher
        self.skipped: dict[str, Message] = {}  # newest per channel, while nobody listened (lazy)
        self.listened_now = True
        self._checked_at = float("-inf")

    def publisher(self, index: int) -> Publisher:
        output = self.translator.outputs[index]
        return self._publisher(self.name + output.suffix, output)

    def listened(self) -> bool:
        """Whether any output has a subscriber, or its transport cannot tell (then: translate)."""
        now = time.monotonic()
        if now - self._checked_at >= _LISTENERS_CHECK_S:
            self._checked_at = now
            counts = [
                self.publisher(index).subscriber_count() for index in range(len(self.translator.outputs))
            ]
            self.listened_now = any(count is None or count > 0 for count in counts)
        return self.listened_now

    def skip(self, message: Message) -> None:
        self.skipped.pop(message.channel, None)  # re-inserted: the dict keeps arrival order
        self.skipped[message.channel] = message


class RouteRunner:
    """One route: its mailbox, its lanes (a translator per stream), its publishers, its worker."""

    def __init__(
        self,
        route: Route,
        make_translator: Callable[[], Translator],
        publisher_for: PublisherFor,
        inline: InlineBudget | None = None,
    ) -> None:
        self.route = route
        self.pattern = re.compile(route.source.name)
        self.mailbox = Mailbox(route.rate.policy, route.qos.depth, rate_limited=bool(route.rate.max_hz))
        self.stats = RouteStats()
        # A rate-limited route waits between messages: only its worker can do that.
        self._inline = None if route.rate.max_hz else inline
        self._turn = threading.Lock()  # held by whichever thread translates for this route
        self._make_translator = make_translator
        self._publisher_for = publisher_for
        self.prototype: Translator | None = make_translator()  # made now: errors show at start
        self._lanes: dict[tuple[str | None, ...], _Lane] = {}  # by the source's captured groups
        self._publishers: dict[str, Publisher] = {}  # by full name: lanes may share a topic
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"route {route.name}", daemon=True)
        self._logged: Counter[str] = Counter()

    def offer(self, received: Received) -> None:
        """Called on the transport's thread: keep the message if this route's source matches."""
        match = self.pattern.fullmatch(received.channel)
        if match is not None:
            self.stats.messages_in += 1
            self.stats.bytes_in += len(received.data)
            message = Message(received, match)
            if not self._translated_inline(message):
                self.mailbox.put(message)

    def _translated_inline(self, message: Message) -> bool:
        """Translate on the caller's thread when the route is idle and the budget allows."""
        inline = self._inline
        if inline is None or len(self.mailbox) or not inline.allows() or not self._turn.acquire(False):
            return False
        started = time.perf_counter()
        try:
            self.handle(message)
        finally:
            self._turn.release()
            inline.spent(started, time.perf_counter())
        return True

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()

    def join(self, timeout: float) -> None:
        if self._thread.is_alive():
            self._thread.join(timeout)

    def _run(self) -> None:
        period = 1.0 / self.route.rate.max_hz if self.route.rate.max_hz else 0.0
        next_due = 0.0
        while not self._stop.is_set():
            if period:  # wait out the rate limit; what arrives meanwhile is conflated
                delay = next_due - time.monotonic()
                if delay > 0 and self._stop.wait(delay):
                    break
            if not self.mailbox.wait(timeout=0.1):
                with self._turn:
                    self.catch_up()
                continue
            # Taken under the turn: a message translated inline meanwhile is never overtaken.
            with self._turn:
                message = self.mailbox.take()
                if message is not None:
                    next_due = time.monotonic() + period
                    self.handle(message)

    def catch_up(self) -> None:
        """A lazy route's lanes that skipped messages and now have a subscriber translate them."""
        for lane in list(self._lanes.values()):
            if lane.skipped and lane.listened():
                self._replay(lane)

    def _replay(self, lane: _Lane) -> None:
        skipped, lane.skipped = lane.skipped, {}
        for message in skipped.values():
            # Kept while nobody listened: how long it waited is no latency of the bridge's.
            self._translate(lane, message, latency=False)

    def _publisher(self, name: str, output: Output) -> Publisher:
        publisher = self._publishers.get(name)
        if publisher is None:
            publisher = self._publishers[name] = self._publisher_for(name, output)
        return publisher

    def _lane(self, message: Message) -> _Lane:
        key = message.match.groups()
        lane = self._lanes.get(key)
        if lane is None:
            translator, self.prototype = self.prototype or self._make_translator(), None
            name = destination_name(self.route.destination.name, message.match)
            lane = self._lanes[key] = _Lane(name, translator, self._publisher)
        return lane

    def handle(self, message: Message) -> None:
        """Translate and publish one message; errors are counted and reported, never raised."""
        try:
            lane = self._lane(message)
            lane.translator.observe(message.received)
            if self.route.lazy:
                if not lane.listened():
                    lane.skip(message)
                    self.stats.idle_skipped += 1
                    return
                if lane.skipped:  # a subscriber just appeared: what came before goes first
                    lane.skipped.pop(message.channel, None)
                    self._replay(lane)
        except Exception as error:  # a bug in a translator's bookkeeping or a transport
            self._error(f"crash:{type(error).__name__}", f"{message.channel}: {traceback.format_exc()}")
            return
        self._translate(lane, message)

    def _translate(self, lane: _Lane, message: Message, latency: bool = True) -> None:
        started = time.perf_counter()
        try:
            with collecting() as skipped:
                outputs = lane.translator.translate(message.received)
        except BridgeError as error:
            self._error(type(error).__name__, f"{message.channel}: {error}")
            return
        except Exception as error:  # a bug in a translator: report it, keep serving
            self._error(f"crash:{type(error).__name__}", f"{message.channel}: {traceback.format_exc()}")
            return
        self.stats.translate_ms.append((time.perf_counter() - started) * 1e3)
        for part in skipped:  # the rest of the message is translated
            if isinstance(part, BridgeError):  # a part that failed (one image of an array): an error
                self._error(type(part).__name__, f"{message.channel}: {part}")
            else:  # a geometry a target cannot write: a warning
                self._count(self.stats.warnings, "skipped_geometry", f"{message.channel}: {part}")
        for index, payload in outputs:
            try:
                lane.publisher(index).publish(payload)
            except Exception as error:  # the transport refused: count it, go on with the rest
                self._error(f"publish:{type(error).__name__}", f"{lane.name}: {error}")
                continue
            self.stats.messages_out += 1
            self.stats.bytes_out += len(payload)
        if outputs and latency:
            self.stats.latency_ms.append((time.time_ns() // 1000 - message.received.received_us) / 1e3)

    def _error(self, kind: str, text: str) -> None:
        self._count(self.stats.errors, kind, text)

    def _count(self, counts: Counter[str], kind: str, text: str) -> None:
        counts[kind] += 1
        self._logged[kind] += 1
        count = self._logged[kind]
        if count <= 5 or count % 1000 == 0:  # the first few, then a reminder: never a flood
            log.warning("route %s: %s (%s #%d)", self.route.name, text.rstrip(), kind, count)

    def state(self) -> str:
        if self.route.lazy and self._lanes and not any(lane.listened_now for lane in self._lanes.values()):
            return "idle: no subscriber"
        return "active"

    def snapshot(self) -> dict[str, Any]:
        return self.stats.snapshot(
            self.mailbox.dropped, len(self.mailbox), self.state(), self.mailbox.rate_skipped
        )


def output_qos(route: Route, latched_by_default: bool) -> Qos:
    """A route's QoS for one output or its subscription: durability is the config's, else the translator's."""
    durability = route.qos.durability
    latched = latched_by_default if durability is None else durability == "transient_local"
    return Qos(route.qos.depth, route.qos.reliability == "reliable", latched)


class Router:
    """Every route of a config, the transports they need, and the stats."""

    def __init__(
        self,
        config: BridgeConfig,
        stats_json: str | Path | None = None,
        stats_period: float = 5.0,
        view: StatusView | None = None,
    ) -> None:
        self.config = config
        self.loads = LoadCache(config.load_cache)
        self.stats_json = Path(stats_json) if stats_json else None
        self.stats_period = stats_period
        self.view = view or LogLines()
        self.transports: dict[str, Transport] = {}
        self.routes: list[RouteRunner] = []
        self._inline = InlineBudget()
        self._stop = threading.Event()
        self._started = False
        try:
            for name in config.transports():
                self.transports[name] = TRANSPORTS.get(name)(config.settings(name))
            for route in config.routes:
                self.routes.append(self._runner(route))
        except BaseException:
            self._close_transports()
            raise

    def _runner(self, route: Route) -> RouteRunner:
        source = self.transports[route.source.transport]
        translator_class = TRANSLATORS.get(route.translator)
        options = route.translator_options()
        reply = self._replier(route) if translator_class.replies is not None else None

        def make_translator() -> Translator:
            translator = translator_class(options, self.loads)
            if reply is not None:
                translator.reply = reply
            return translator

        runner = RouteRunner(route, make_translator, self._publisher_factory(route), self._inline)
        translator = runner.prototype
        assert translator is not None
        # Before anything runs, each transport checks it has every type the route uses: a missing
        # interface is one clear line at start, not an error per message.
        source.require(translator.reads[:1] + ((translator.replies,) if translator.replies else ()))
        self.transports[route.destination.transport].require(output.type for output in translator.outputs)
        source.subscribe(route.source.name, translator.reads[0], output_qos(route, False), runner.offer)
        return runner

    def _publisher_factory(self, route: Route) -> PublisherFor:
        transport = self.transports[route.destination.transport]

        def make(name: str, output: Output) -> Publisher:
            return transport.publisher(name, output.type, output_qos(route, output.latched))

        return make

    def _replier(self, route: Route) -> Callable[[str, bytes], None]:
        """Publishing back on the route's source transport, a publisher per channel."""
        transport = self.transports[route.source.transport]
        message_type = TRANSLATORS.get(route.translator).replies
        assert message_type is not None
        publishers: dict[str, Publisher] = {}

        def reply(channel: str, data: bytes) -> None:
            publisher = publishers.get(channel)
            if publisher is None:
                publisher = publishers[channel] = transport.publisher(channel, message_type, Qos())
            publisher.publish(data)

        return reply

    def start(self) -> None:
        """Start the workers and the transports (`run` does it unless it was done already)."""
        if self._started:
            return
        self._started = True
        for runner in self.routes:
            runner.start()
        for transport in self.transports.values():
            transport.start()
        where = ", ".join(transport.describe() for transport in self.transports.values())
        log.info("viewer-bridge: %d routes running (%s)", len(self.routes), where)

    def stop(self) -> None:
        self._stop.set()

    def run(self, duration: float | None = None) -> None:
        """Serve until `stop()` (a signal handler calls it), `duration` ends, or a finite source ends."""
        self.start()
        deadline = None if duration is None else time.monotonic() + duration
        next_report = time.monotonic() + self.stats_period
        try:
            while not self._ending(deadline):
                remaining = None if deadline is None else deadline - time.monotonic()
                self._stop.wait(min(0.1, remaining) if remaining is not None else 0.1)
                # The last report is close()'s: none just before it, so it is printed once.
                if time.monotonic() >= next_report and not self._ending(deadline):
                    next_report += self.stats_period
                    self.report()
        finally:
            self.close()

    def _ending(self, deadline: float | None) -> bool:
        """Whether to stop: asked to, the duration is over, or a finite source ended (said once)."""
        if self._stop.is_set() or (deadline is not None and time.monotonic() >= deadline):
            return True
        ended = self._source_ended()
        if ended is not None and self._idle():
            log.info("viewer-bridge: %s has ended: stopping", ended)
            self._stop.set()
            return True
        return False

    def _source_ended(self) -> str | None:
        """The transport (described) whose finite source, a replayed log, has ended, or None."""
        ended = (transport.describe() for transport in self.transports.values() if transport.finished())
        return next(ended, None)

    def _idle(self) -> bool:
        return all(len(runner.mailbox) == 0 for runner in self.routes)

    def close(self) -> None:
        """Stop the workers, write the last stats, close the transports."""
        for runner in self.routes:
            runner.stop()
        for runner in self.routes:
            runner.join(timeout=2)
        self.report()
        self.view.close()
        self._close_transports()

    def _close_transports(self) -> None:
        for transport in self.transports.values():
            transport.close()

    def snapshot(self) -> dict[str, Any]:
        """Per route stats; transports' own error counts under `transports`."""
        snapshot: dict[str, Any] = {runner.route.name: runner.snapshot() for runner in self.routes}
        errors = {name: dict(t.errors()) for name, t in self.transports.items() if t.errors()}
        if errors:
            snapshot["transports"] = {name: {"errors": counts} for name, counts in errors.items()}
        return snapshot

    def report(self) -> None:
        """The routes' stats to the status view, and to the JSON file when asked for."""
        snapshot = self.snapshot()
        self.view.show(snapshot)
        if self.stats_json is not None:
            temporary = self.stats_json.with_suffix(".tmp")
            temporary.write_text(json.dumps(snapshot, indent=2))
            temporary.replace(self.stats_json)
