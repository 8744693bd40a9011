"""The router: runs each configured route's translator between transports.

Threads: each transport delivers on a thread of its own and only hands the bytes to the routes
whose source matches (a dictionary insert); each route has a worker thread that translates and
publishes. Between the two sits a `Mailbox`, bounded: with the `latest` policy it keeps the
newest message per channel (a slow consumer gets the newest draw, never a backlog; a draw
never displaces a load, which is on another channel), with `all` a FIFO of `qos.depth` that
drops its oldest. Every drop, error and crash is counted per route and kind; a translator that
raises skips that message only.
"""

from __future__ import annotations

import json
import logging
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
from bridge.translators import TRANSLATORS, LoadCache, Output, Translator
from bridge.transports.lcm import LcmBus, LogReplay, open_bus

log = logging.getLogger("viewer_bridge")


@dataclass(slots=True)
class Message:
    channel: str
    data: bytes
    received_us: int
    match: re.Match[str]


class Mailbox:
    """Messages between a transport thread and a route's worker; never grows without bound."""

    def __init__(self, policy: str, depth: int) -> None:
        self.keep_latest = policy == "latest"
        self._latest: OrderedDict[str, Message] = OrderedDict()
        self._fifo: deque[Message] = deque()
        self._depth = depth
        self._ready = threading.Condition()
        self.dropped = 0

    def put(self, message: Message) -> None:
        with self._ready:
            if self.keep_latest:
                if self._latest.pop(message.channel, None) is not None:
                    self.dropped += 1  # superseded before it was translated
                self._latest[message.channel] = message
            else:
                if len(self._fifo) >= self._depth:
                    self._fifo.popleft()
                    self.dropped += 1
                self._fifo.append(message)
            self._ready.notify()

    def get(self, timeout: float) -> Message | None:
        with self._ready:
            if not self._latest and not self._fifo:
                self._ready.wait(timeout)
            if self._latest:
                return self._latest.popitem(last=False)[1]
            return self._fifo.popleft() if self._fifo else None

    def __len__(self) -> int:
        return len(self._latest) + len(self._fifo)


_SAMPLES = 4096  # latency and translate-time samples kept per route (a ring)


@dataclass
class RouteStats:
    messages_in: int = 0
    messages_out: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    errors: Counter[str] = field(default_factory=Counter)
    translate_ms: deque[float] = field(default_factory=lambda: deque(maxlen=_SAMPLES))
    latency_ms: deque[float] = field(default_factory=lambda: deque(maxlen=_SAMPLES))

    def snapshot(self, dropped: int, queued: int) -> dict[str, Any]:
        return {
            "messages_in": self.messages_in,
            "messages_out": self.messages_out,
            "bytes_in": self.bytes_in,
            "bytes_out": self.bytes_out,
            "errors": dict(self.errors),
            "dropped": dropped,
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


Publish = Callable[[bytes], None]


class RouteRunner:
    """One route: its mailbox, its translator, its publishers and its worker thread."""

    def __init__(
        self, route: Route, translator: Translator, publisher_for: Callable[[str, Output], Publish]
    ) -> None:
        self.route = route
        self.translator = translator
        self.pattern = re.compile(route.source.name)
        self.mailbox = Mailbox(route.rate.policy, route.qos.depth)
        self.stats = RouteStats()
        self._publisher_for = publisher_for
        self._publishers: dict[str, Publish] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"route {route.name}", daemon=True)
        self._logged: Counter[str] = Counter()

    def offer(self, channel: str, data: bytes, received_us: int) -> None:
        """Called on the transport's thread: keep the message if this route's source matches."""
        match = self.pattern.fullmatch(channel)
        if match is not None:
            self.stats.messages_in += 1
            self.stats.bytes_in += len(data)
            self.mailbox.put(Message(channel, data, received_us, match))

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
            message = self.mailbox.get(timeout=0.1)
            if message is None:
                continue
            next_due = time.monotonic() + period
            self.handle(message)

    def handle(self, message: Message) -> None:
        """Translate and publish one message; errors are counted and reported, never raised."""
        started = time.perf_counter()
        try:
            outputs = self.translator.translate(message.channel, message.data)
        except BridgeError as error:
            self._error(type(error).__name__, f"{message.channel}: {error}")
            return
        except Exception as error:  # a bug in a translator: report it, keep serving
            self._error(f"crash:{type(error).__name__}", f"{message.channel}: {traceback.format_exc()}")
            return
        self.stats.translate_ms.append((time.perf_counter() - started) * 1e3)
        for index, payload in outputs:
            output = self.translator.outputs[index]
            try:
                name = destination_name(self.route.destination.name, message.match) + output.suffix
                self._publisher(name, output)(payload)
            except Exception as error:  # the transport refused: count it, go on with the rest
                self._error(f"publish:{type(error).__name__}", f"{self.route.destination.name}: {error}")
                continue
            self.stats.messages_out += 1
            self.stats.bytes_out += len(payload)
        if outputs:
            self.stats.latency_ms.append((time.time_ns() // 1000 - message.received_us) / 1e3)

    def _publisher(self, name: str, output: Output) -> Publish:
        publisher = self._publishers.get(name)
        if publisher is None:
            publisher = self._publishers[name] = self._publisher_for(name, output)
        return publisher

    def _error(self, kind: str, text: str) -> None:
        self.stats.errors[kind] += 1
        self._logged[kind] += 1
        count = self._logged[kind]
        if count <= 5 or count % 1000 == 0:  # the first few, then a reminder: never a flood
            log.warning("route %s: %s (%s #%d)", self.route.name, text.rstrip(), kind, count)

    def snapshot(self) -> dict[str, Any]:
        return self.stats.snapshot(self.mailbox.dropped, len(self.mailbox))


def _ros_qos(route: Route, latched_by_default: bool) -> Any:
    """The route's QoS for rclpy; durability is the config's, else the translator's choice."""
    from bridge.transports.ros2 import qos_profile  # rclpy only when a route needs it

    durability = route.qos.durability
    latched = latched_by_default if durability is None else durability == "transient_local"
    return qos_profile(route.qos.depth, route.qos.reliability == "reliable", latched)


class Router:
    """Every route of a config, the transports they need, and the stats."""

    def __init__(
        self,
        config: BridgeConfig,
        stats_json: str | Path | None = None,
        stats_period: float = 5.0,
    ) -> None:
        self.config = config
        self.loads = LoadCache(config.load_cache)
        self.stats_json = Path(stats_json) if stats_json else None
        self.stats_period = stats_period
        self.lcm: LcmBus | LogReplay | None = None
        self.ros: Any = None
        self.routes: list[RouteRunner] = []
        self._lcm_routes: list[RouteRunner] = []
        self._stop = threading.Event()
        self._started = False
        uses = {route.source.transport for route in config.routes} | {
            route.destination.transport for route in config.routes
        }
        if "lcm" in uses:
            self.lcm = open_bus(config.lcm.url)
        if "ros" in uses:
            from bridge.transports.ros2 import RosNode  # rclpy only when a route needs it

            settings = config.ros
            self.ros = RosNode(settings.node, settings.namespace, settings.use_sim_time)
        self.ign: Any = None
        if "ign" in uses:
            from bridge.transports.ign import IgnNode

            self.ign = IgnNode(config.ign.partition, config.ign.ip)
        for route in config.routes:
            translator = TRANSLATORS[route.translator](dict(route.options), self.loads)
            if route.source.transport == "lcm" and isinstance(self.lcm, LcmBus):
                translator.reply = self.lcm.publish  # a replayed log has nobody to answer
            runner = RouteRunner(route, translator, self._publisher_factory(route))
            self.routes.append(runner)
            if route.source.transport == "lcm":
                self._lcm_routes.append(runner)  # one LCM subscription serves them all: see start()
            elif route.source.transport == "ign":
                self.ign.subscribe(route.source.name, translator.source_type, runner.offer)
            else:
                self._subscribe_ros(runner)

    def _subscribe_ros(self, runner: RouteRunner) -> None:
        qos = _ros_qos(runner.route, latched_by_default=False)
        self.ros.subscribe(runner.route.source.name, runner.translator.source_type, qos, runner.offer)

    def _publisher_factory(self, route: Route) -> Callable[[str, Output], Publish]:
        def make(name: str, output: Output) -> Publish:
            if route.destination.transport == "lcm":
                assert self.lcm is not None
                bus = self.lcm
                return lambda data: bus.publish(name, data)
            if route.destination.transport == "ign":
                node = self.ign
                node.advertise(name, output.typename)  # seen by `ign topic -l` from the first message on
                return lambda data: node.publish(name, data, output.typename)
            qos = _ros_qos(route, latched_by_default=output.latched)
            publish: Publish = self.ros.publisher(name, output.typename, qos)
            return publish

        return make

    def _dispatch(self, channel: str, data: bytes, received_us: int) -> None:
        for runner in self._lcm_routes:
            runner.offer(channel, data, received_us)

    def start(self) -> None:
        """Start the workers and the transports (`run` does it unless it was done already)."""
        if self._started:
            return
        self._started = True
        for runner in self.routes:
            runner.start()
        if self.ros is not None:
            self.ros.start()
        if self.ign is not None:
            self.ign.start()
        if self.lcm is not None:
            self.lcm.subscribe(".*", self._dispatch)
            self.lcm.start()
        where = [f"LCM {self.lcm.url}"] if self.lcm is not None else []
        if self.ros is not None:
            where.append(f"ROS 2 node {self.ros.node.get_fully_qualified_name()}")
        if self.ign is not None:
            where.append(f"ign-transport partition {self.ign.partition} on {self.ign.address}")
        log.info("viewer-bridge: %d routes running (%s)", len(self.routes), ", ".join(where))

    def stop(self) -> None:
        self._stop.set()

    def run(self, duration: float | None = None) -> None:
        """Serve until `stop()` (a signal handler calls it), `duration` ends, or a replayed log ends."""
        self.start()
        deadline = None if duration is None else time.monotonic() + duration
        next_report = time.monotonic() + self.stats_period
        try:
            while not self._stop.is_set():
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    break
                if isinstance(self.lcm, LogReplay) and self.lcm.finished.is_set() and self._idle():
                    break
                self._stop.wait(min(0.1, remaining) if remaining is not None else 0.1)
                if time.monotonic() >= next_report:
                    next_report += self.stats_period
                    self.report()
        finally:
            self.close()

    def _idle(self) -> bool:
        return all(len(runner.mailbox) == 0 for runner in self.routes)

    def close(self) -> None:
        """Stop the workers, write the last stats, close the transports."""
        for runner in self.routes:
            runner.stop()
        for runner in self.routes:
            runner.join(timeout=2)
        self.report()
        if self.lcm is not None:
            self.lcm.close()
        if self.ros is not None:
            self.ros.close()
        if self.ign is not None:
            self.ign.close()

    def snapshot(self) -> dict[str, Any]:
        """Per route stats; transports' own error counts under `transports`."""
        snapshot: dict[str, Any] = {runner.route.name: runner.snapshot() for runner in self.routes}
        if self.ign is not None and self.ign.errors:
            snapshot["transports"] = {"ign": {"errors": dict(self.ign.errors)}}
        return snapshot

    def report(self) -> None:
        """One log line per route, and the JSON file when asked for."""
        snapshot = self.snapshot()
        for name, stats in snapshot.items():
            if name == "transports":
                log.info("transports: %s", stats)
                continue
            errors = sum(stats["errors"].values())
            latency = stats["latency_ms"]
            log.info(
                "route %s: in %d out %d errors %d dropped %d latency p50 %s p99 %s ms",
                name,
                stats["messages_in"],
                stats["messages_out"],
                errors,
                stats["dropped"],
                latency["p50"],
                latency["p99"],
            )
        if self.stats_json is not None:
            temporary = self.stats_json.with_suffix(".tmp")
            temporary.write_text(json.dumps(snapshot, indent=2))
            temporary.replace(self.stats_json)
