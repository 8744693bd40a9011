"""The `Router`: runs each configured route's translator between transports.

The data path of one message:

    transport thread                     route worker thread
    ----------------                     -------------------
    Received --offer--> Mailbox ------>  lane (per stream) -> observe -> [lazy?] -> translate
    (one per message,   (per route,                                 -> publisher per output
     shared by routes)   bounded)

`Router` makes the transports a config names, a `RouteRunner` per route
(`viewer_bridge.router.runner`: lanes, lazy routes, its worker) and reports their stats
(`viewer_bridge.router.stats`); how a message waits for a worker, or is translated at once on the
transport's thread, is `viewer_bridge.router.flow`. The router knows transports and translators only
through their interfaces (`viewer_bridge.transports.base.Transport`, `viewer_bridge.translators.base.Translator`)
and their registries: no transport or format is named here.

Offline, nothing runs on threads: `Router.feed` hands one message to every matching route of a
source and translates and publishes it at once, on the caller's thread (`convert` feeds a log
this way to routes that end in an MCAP file).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from viewer_bridge.config.bridge import ROS_TOPICS_TRANSLATOR, BridgeConfig, Route
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.router import stats
from viewer_bridge.router.echoes import Echoes
from viewer_bridge.router.flow import InlineBudget
from viewer_bridge.router.runner import Destinations, PublisherFor, RouteRunner, SaidOnce
from viewer_bridge.router.status import LogLines, Snapshot, StatusView, snapshot_of
from viewer_bridge.shared import RosDefinitions, Shared, definitions_of
from viewer_bridge.translators.base import Output, Translator
from viewer_bridge.translators.load_cache import LoadCache
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import (
    DEPTH,
    DURABILITY,
    RELIABILITY,
    Express,
    ExpressFor,
    Publisher,
    Qos,
    Received,
    Transport,
)
from viewer_bridge.transports.command_policy import COMMAND_FLAG
from viewer_bridge.transports.playback import Timeline, Timelines
from viewer_bridge.transports.registry import TRANSPORTS
from viewer_bridge.transports.ros_names import ChannelNames
from viewer_bridge.util.words import counted

log = logging.getLogger("viewer_bridge")


def output_qos(route: Route, latched_by_default: bool, told: Callable[[str], None] | None = None) -> Qos:
    """A route's QoS for one output: durability is the config's, else the translator's; `told`
    hears of subscribers whose QoS cannot match."""
    durability = route.qos.durability
    latched = latched_by_default if durability is None else durability == "transient_local"
    return Qos(route.qos.depth, route.qos.reliability == "reliable", latched, told=told)


def source_qos(runner: RouteRunner) -> Qos:
    """A route's QoS for its subscription: each policy its config leaves unset follows the
    topic's publishers, where the transport finds them in a ROS graph. A route that writes
    commands keeps one message (KEEP_LAST 1: after a stall, only the newest is there to take) and
    subscribes only to the names whose channel the allow-list names."""
    route, commands = runner.route, runner.commands is not None
    asked = route.qos.model_fields_set
    follow = {RELIABILITY} - asked | ({DURABILITY} if route.qos.durability is None else set())
    if not commands and DEPTH not in asked:
        follow.add(DEPTH)
    qos = output_qos(route, False, runner.qos_mismatch)
    if commands:
        return replace(qos, depth=1, follow=frozenset(follow), admits=runner.admits)
    return replace(qos, follow=frozenset(follow))


def unwritten(config: BridgeConfig, transport: str, express_for: ExpressFor) -> ExpressFor:
    """`express_for` for the channels of `transport` that no route may write, None for the
    others: only a message on a channel the bridge itself writes can be its own come back, so
    only those need the loop guard to read each message. A route that writes commands writes
    only what `commands.allow` allows (`CommandPolicy.allows`), any other its destination's
    name, or any name when that is a template (`{1}`)."""
    commands = config.commands
    names: set[str] = set()
    allowed = False
    for route in config.routes:
        if route.destination.transport != transport:
            continue
        if TRANSLATORS.get(route.translator).commands:
            allowed = True
        elif "{" in route.destination.name:
            return lambda channel: None  # it may write any channel: every one is guarded
        else:
            names.add(route.destination.name)

    def express_unwritten(channel: str) -> Express | None:
        if channel in names or (allowed and commands.allows(channel)):
            return None
        return express_for(channel)

    return express_unwritten


class Router:
    """Every route of a config, the transports they need, and the stats."""

    def __init__(
        self,
        config: BridgeConfig,
        stats_json: str | Path | None = None,
        stats_period: float = 5.0,
        view: StatusView | None = None,
        ros_definitions: RosDefinitions | None = None,
        timeline: Timeline | None = None,
    ) -> None:
        """`ros_definitions`: where the ros transport finds the `.msg` definitions of an interface
        package it lacks, to build it while the other routes run (see `RosDefinitions`).
        `timeline`: what the transports play and clients drive (`viewer-bridge play`'s log), or None."""
        self.config = config
        self.stats_json = Path(stats_json) if stats_json else None
        self.stats_period = stats_period
        self.view = view or LogLines()
        # What the transports and translators share: the known LCM types (loaded once, here: a
        # bad source stops the start) and the ROS 2 definitions of their interface packages (for
        # building one the ros transport lacks), one Foxglove context, the message time, the last
        # Drake load per channel (kept in the config's folder, if it names one), the clock (`time:`).
        lcm_types = TypeLibrary.load(config.lcm_types, drake=config.drake_lcm_types)
        # What the config decides, given to them: the load cache (in its folder), the commands'
        # allow-list (a server offers publishing only when a command can land), the timeline played.
        given = (LoadCache(config.load_cache), config.commands, Timelines(timeline))
        self.shared = Shared(lcm_types, ros_definitions or definitions_of(lcm_types), config.time, given)
        for warning in lcm_types.warnings:
            log.warning("viewer-bridge: %s", warning)
        self.transports: dict[str, Transport] = {}
        self.routes: list[RouteRunner] = []
        self._sourced: dict[str, list[RouteRunner]] = {}  # by source transport, for `feed`
        self._inline = InlineBudget()
        # the loop guard of names both published and subscribed
        self._echoes = Echoes(self.shared.message_time)
        self._stop = threading.Event()
        self._started = False
        try:
            for name in config.transports():
                self.transports[name] = TRANSPORTS.get(name).create(config.settings(name), self.shared)
            for route in config.routes:
                runner = self._runner(route)
                self.routes.append(runner)
                self._sourced.setdefault(route.source.transport, []).append(runner)
        except BaseException:
            self._close_transports()
            raise

    def _runner(self, route: Route) -> RouteRunner:
        source = self.transports[route.source.transport]
        translator_class = TRANSLATORS.get(route.translator)
        options = route.translator_options()
        reply = self._replier(route) if translator_class.replies is not None else None

        def make_translator() -> Translator:
            return translator_class(options, shared=self.shared, reply=reply)

        runner = RouteRunner(
            route,
            make_translator,
            self._publisher_factory(route),
            self._inline,
            self.shared.message_time,
            source.rejected,
            self.config.commands if translator_class.commands else None,
            self.shared.get(ChannelNames),
            self.shared.get(SaidOnce),
            self.shared.get(Destinations) if translator_class.exclusive else None,
            plain_destination=self.transports[route.destination.transport].plain_publishers,
        )
        translator = runner.prototype
        assert translator is not None
        # Before anything runs, each transport checks it has every type the route uses (what the
        # translator declares it writes, whatever outputs it adds later): a missing interface is
        # one clear line at start, not an error per message.
        source.require(translator.reads[:1] + ((translator.replies,) if translator.replies else ()))
        self.transports[route.destination.transport].require(translator_class.writes(options))
        published = any(other.destination.transport == route.source.transport for other in self.config.routes)
        deliver = self._echoes.deliver(route.source.transport, runner.offer, runner.came_back, published)
        source.subscribe(route.source.name, translator.reads[0], source_qos(runner), deliver)
        if deliver == runner.offer:  # no loop guard between: the route's express path may serve it
            source.offer_express(deliver, runner.express)
        else:  # the guard reads the channels the bridge may write there; the others may go express
            source.offer_express(deliver, unwritten(self.config, route.source.transport, runner.express))
        return runner

    def _publisher_factory(self, route: Route) -> PublisherFor:
        transport = self.transports[route.destination.transport]
        told = self._told(route)

        def make(name: str, output: Output) -> Publisher:
            qos = output_qos(route, output.latched, told)
            publisher = transport.publisher(name, output.type, qos)
            subscribed = self._subscribed(route.destination.transport, name)
            return self._echoes.publisher(
                route.destination.transport, name, publisher, route.source.transport, subscribed
            )

        return make

    def _told(self, route: Route) -> Callable[[str], None]:
        """What a route's publishers call when a subscriber's QoS cannot match: its runner counts it
        (the runner is made after its publisher factory, so it is looked up when it happens)."""

        def told(text: str) -> None:
            for runner in self.routes:
                if runner.route is route:
                    runner.qos_mismatch(text)

        return told

    def _subscribed(self, transport: str, name: str) -> bool:
        """Whether a route reads `name` on `transport` (then what is published there may come back)."""
        return any(
            runner.route.source.transport == transport and runner.pattern.fullmatch(name)
            for runner in self.routes
        )

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
        log.info("viewer-bridge: %s running (%s)", counted(len(self.routes), "route"), where)
        self._say_ros_topics()
        self._say_commands()

    def _say_ros_topics(self) -> None:
        """One line naming the ROS 2 topics `ros_topics` carries onto LCM, and from where."""
        if not self.config.ros_topics:
            return
        graphs = [runner.route.source.transport for runner in self.routes
                  if runner.route.translator == ROS_TOPICS_TRANSLATOR]  # fmt: skip
        log.info("viewer-bridge: ros_topics: %s from %s onto LCM, each on its topic's name without the leading /",
                 " | ".join(self.config.ros_topics), ", ".join(dict.fromkeys(graphs)) or "no ROS graph")  # fmt: skip

    def _say_commands(self) -> None:
        """One line naming what may be commanded and from where, when routes write commands, and
        each source's warning when commands can come from past this machine."""
        sources = [runner.route.source.transport for runner in self.routes if runner.commands is not None]
        if not sources:
            if self.config.commands.allow:  # allowed, and nothing could ever write them
                log.warning("viewer-bridge: commands: %s allowed, but no route of the config writes LCM "
                            "(ros_to_lcm): nothing will be commanded", self.config.commands.describe())  # fmt: skip
            return
        policy = self.config.commands
        if not policy.allow:
            log.info("viewer-bridge: commands: none (the way back writes no LCM channel until one is named: %s REGEX)",
                     COMMAND_FLAG)  # fmt: skip
            return
        exposures = [self.transports[name].exposure() for name in dict.fromkeys(sources)]
        who = ", ".join(exposure.who for exposure in exposures)
        log.info(
            "viewer-bridge: commands: %s from %s (max_age_ms %g)", policy.describe(), who, policy.max_age_ms
        )
        for exposure in exposures:
            if exposure.warning is not None:
                log.warning("viewer-bridge: %s", exposure.warning)
        for collision in policy.collisions():
            log.warning("viewer-bridge: commands: %s", collision)

    def stop(self) -> None:
        self._stop.set()

    def feed(self, transport: str, received: Received) -> None:
        """Offline, instead of `start`: `received` as if the `transport` had received it, translated
        and published at once, on this thread, by every route whose source is that transport and
        matches it (in the config's order; nothing is queued, dropped or rate-limited)."""
        for runner in self._sourced.get(transport, ()):
            runner.feed(received)

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

    def snapshot(self) -> Snapshot:
        """Per route stats; transports' own error counts under `transports`."""
        routes = {runner.route.name: runner.snapshot() for runner in self.routes}
        return snapshot_of(routes, {name: dict(t.errors()) for name, t in self.transports.items()})

    def report(self) -> None:
        """The routes' stats to the status view, and to the JSON file when asked for."""
        stats.report_safely(self.snapshot, self.view, self.stats_json)
