"""One route at work: `RouteRunner` takes the messages its source matches, runs its translator
per stream and publishes, on the transport's thread or on its own worker (`viewer_bridge.router.flow`).

A route has one translator per stream (a "lane"): per set of groups its source regex captures,
so the illustration and proximity streams a route matches never share a translator's state,
even when they publish on one topic (`/tf`). A lazy route that skipped messages while nobody
listened keeps the newest per channel and translates them the moment a subscriber appears, so
the subscriber gets the model and the latest poses at once, not at the next draw. Every drop,
error and crash is counted per route and kind (`viewer_bridge.router.stats`); a translator that raises
skips that message only.
"""

from __future__ import annotations

import logging
import threading
import time
import traceback
from collections import Counter
from collections.abc import Callable

from viewer_bridge.config.bridge import Route, destination_name
from viewer_bridge.errors import BridgeError, Held
from viewer_bridge.model.skipped import Skipped, current_collector, thread_collector
from viewer_bridge.router.echoes import GuardedPublisher
from viewer_bridge.router.flow import InlineBudget, Mailbox, Message
from viewer_bridge.router.stats import RouteStats
from viewer_bridge.router.status import RouteSnapshot
from viewer_bridge.shared import MessageTime
from viewer_bridge.translators.base import Output, Translator
from viewer_bridge.transports.base import (
    Closable,
    Express,
    MessageType,
    Publisher,
    Received,
    hand_over,
    size_of,
)
from viewer_bridge.transports.command_policy import CommandPolicy
from viewer_bridge.transports.ros_names import ChannelNames
from viewer_bridge.util.channels import ChannelPattern

log = logging.getLogger("viewer_bridge")

PublisherFor = Callable[[str, Output], Publisher]  # (full name, output) -> a publisher
_LISTENERS_CHECK_S = 0.25  # how often a lazy route asks its publishers whether anyone listens
# Channels a route counts held messages on one by one; the rest are counted together, so that a
# flood of new channel names (a hostile peer's topics) cannot grow the stats without bound.
MAX_HELD_CHANNELS = 1000
OTHER_CHANNELS = "(other channels)"
# A full route looks for quiet streams (`stream_idle_s`) at most this often: lanes gone quiet one by
# one under a flood of new names cost one scan of the route's lanes a second, not one per message.
RECLAIM_SCAN_S = 1.0
# A `policy: all` route whose translations take less than this on average translates inline
# past the thread's budget: a few wake-ups' worth (20-60 us each on the 2-core test VM).
QUICK_S = 100e-6
# The express path (`RouteRunner.express`) leaves one message in this many to the full path, which
# times it (`translate_ms`, latency), asks for listeners when due, and fills the inline budget for
# the messages carried since: the stats sample the stream instead of costing every message.
EXPRESS_SAMPLE = 128
# The express path carries messages up to this size: a quick translation of one takes microseconds
# (a copy, a transcoding), so it needs no timing. A larger one takes the full path, whose timing
# keeps a slow route to the inline budget. A size, not a time: the same on any machine, and under
# valgrind (bench/instructions.py), where every time is some 50 times longer.
EXPRESS_MAX_BYTES = 64 * 1024


class SaidOnce:
    """What a router's routes have said once between them (a held message's channel and kind):
    two routes reading one channel of an unknown type log it once, and each counts it. Bounded
    as the held channels are (`MAX_HELD_CHANNELS` per route), times the few kinds."""

    def __init__(self) -> None:
        self._said: set[tuple[str, ...]] = set()
        self._lock = threading.Lock()  # routes hold messages on their own threads

    def first(self, *key: str) -> bool:
        """Whether `key` is said now for the first time."""
        with self._lock:
            if key in self._said:
                return False
            self._said.add(key)
            return True


Place = tuple[str, str]  # (transport, channel or topic)


class Destinations:
    """Which stream each destination of an exclusive translator carries (`Translator.exclusive`):
    the source (transport, channel) that first asked for it, across a router's routes. Bounded by
    the routes' streams (`max_streams` each)."""

    def __init__(self) -> None:
        self._owners: dict[Place, Place] = {}
        self._lock = threading.Lock()  # routes make lanes on their own threads

    def claim(self, destination: Place, source: Place) -> Place:
        """The source that carries `destination`: `source` if it is the first to ask."""
        with self._lock:
            return self._owners.setdefault(destination, source)

    def release(self, destination: Place, source: Place) -> None:
        """`source` carries `destination` no more (its stream went quiet): the next to ask has it."""
        with self._lock:
            if self._owners.get(destination) == source:
                del self._owners[destination]


class _Lane:
    """One stream of a route: its translator, the names it publishes on, what it skipped."""

    def __init__(
        self,
        name: str,
        translator: Translator,
        publisher: Callable[[str, Output], Publisher],
        channel: str = "",
        now: float = 0.0,
    ) -> None:
        self.name = name
        self.translator = translator
        self.channel = channel  # the source channel it was made for (an exclusive claim's owner)
        self.used_at = now  # when it last had a message (the route's clock): a quiet lane is reclaimed
        self.used = False  # a message came since the last reclaim scan (which then moves `used_at`)
        self._publisher = publisher
        # Each output's publisher by index, while the output at that index is the same (a
        # translator adds outputs as it goes): no name or key made per message.
        self.made: dict[int, tuple[Output, Publisher]] = {}
        self.skipped: dict[str, Message] = {}  # newest per channel, while nobody listened (lazy)
        self.listened_now = True
        self.checked_at = float("-inf")  # when `listened` last asked the publishers
        # Whether the translator keeps books on every message: most do not (no call per message).
        self.observes = type(translator).observe is not Translator.observe
        self.reclaimed = False  # let go (`RouteRunner._reclaim`): its express path carries no more
        self.express: Express | None = None  # its express path, made for the publishers it had then
        self.express_made = 0  # how many publishers it had then

    def names(self) -> list[tuple[str, MessageType]]:
        """The (name, type) of each publisher it made: what it gives back when reclaimed."""
        return [(self.name + output.suffix, output.type) for output, _ in self.made.values()]

    def closable(self) -> bool:
        """Whether all it holds can be let go: every publisher it made frees its transport's state
        when closed (a Zenoh or gz publisher does not: such a lane is never reclaimed)."""
        return all(isinstance(publisher, Closable) for _, publisher in self.made.values())

    def publisher(self, index: int) -> Publisher:
        output = self.translator.outputs[index]
        made = self.made.get(index)
        if made is None or made[0] is not output:
            made = self.made[index] = (output, self._publisher(self.name + output.suffix, output))
        return made[1]

    def listened(self) -> bool:
        """Whether any output has a subscriber, or its transport cannot tell (then: translate).

        Raises `Held` when an output cannot have a publisher yet (its interface is being built):
        nothing to translate for, nobody to ask."""
        now = time.monotonic()
        if now - self.checked_at >= _LISTENERS_CHECK_S:
            self.checked_at = now
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
        message_time: MessageTime | None = None,
        rejected: Callable[[Received, BridgeError], None] | None = None,
        commands: CommandPolicy | None = None,
        names: ChannelNames | None = None,
        said: SaidOnce | None = None,
        destinations: Destinations | None = None,
        clock: Callable[[], float] = time.monotonic,
        plain_destination: bool = False,
    ) -> None:
        """`commands`: the policy of a route that writes commands (its destinations must be
        allowed; its messages expire after `max_age_ms`), or None for any other route. `names`:
        the router's channels made into ROS name tokens (`{1:topic}`, `{1:channel}`). `said`: what
        the router's routes have logged once (a held channel), or None for the route's own.
        `destinations`: the router's, for a route whose translator is exclusive (each destination
        carries one stream), else None. `clock`: seconds, for how long a stream has been quiet
        (`stream_idle_s`; a test's own clock). `plain_destination`: the destination transport's
        publishers read nothing but their bytes (`Transport.plain_publishers`), so the route may
        have an express path (`express`)."""
        self.route = route
        self.commands = commands
        self._destinations = destinations
        self._names = names
        max_age_ms = route.max_age_ms if route.max_age_ms is not None else commands and commands.max_age_ms
        self._max_age_us = max_age_ms * 1000 if max_age_ms else None
        self._rejected = rejected  # the source transport's `rejected`: a sender may expect an answer
        self.pattern = ChannelPattern(route.source.name)  # a channel's match, once
        self._lazy = route.lazy
        self.mailbox = Mailbox(route.rate.policy, route.qos.depth, rate_limited=bool(route.rate.max_hz))
        self.stats = RouteStats()
        # A rate-limited route waits between messages: only its worker can do that.
        self._inline = None if route.rate.max_hz else inline
        # A route that keeps every message (`policy: all`) and translates it quickly gains nothing
        # from its worker when the receiving thread is busy: each message is translated all the
        # same, and the hand-off's wake-up and GIL switch cost about as much as the translation. At
        # 30,000 messages a second on one core that hand-off was what the core could not carry
        # (92-97% delivered against 100% inline). So such a route translates inline whenever it
        # is idle, while its recent translations took less than `QUICK_S` on average; its time
        # still fills the thread's budget, so the other routes on that thread hand over. A slow one
        # (1000-link markers: hundreds of microseconds) keeps the budget: inline always, it held
        # the receiving thread so long that the quick routes beside it lost draws in the kernel.
        self._keeps_every = route.rate.policy == "all"
        self._cost_s = 0.0  # recent translations' mean (inline or on the worker): one outlier does not decide
        self._turn = threading.Lock()  # held by whichever thread translates for this route
        self._make_translator = make_translator
        self._publisher_for = publisher_for
        self._message_time = MessageTime() if message_time is None else message_time
        self.prototype: Translator | None = make_translator()  # made now: errors show at start
        self._lanes: dict[tuple[str | None, ...], _Lane] = {}  # by the source's captured groups
        self._clock = clock
        # When a full route looks for quiet lanes next: not before one can be quiet for
        # `stream_idle_s`, nor within `RECLAIM_SCAN_S` of the last look.
        self._reclaim_at = float("-inf")
        # By full name and type: lanes may share a topic, a channel's type may change (any LCM type).
        self._publishers: dict[tuple[str, MessageType], Publisher] = {}
        self._said = SaidOnce() if said is None else said  # a held (channel, kind) said once
        self._own_channels: set[str] = set()  # where the bridge's own messages came back to this route
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"route {route.name}", daemon=True)
        self._logged: Counter[str] = Counter()
        # The express path: for a quick `policy: all` route whose translator makes a message's one
        # payload from its bytes alone (`Translator.relays`, `Translator.quick`), onto publishers
        # that take bytes alone, with no age limit to check per message.
        translator_class = type(self.prototype)
        self._expressible = (
            plain_destination
            and self._inline is not None
            and self._keeps_every
            and self._max_age_us is None
            and self.commands is None
            and (translator_class.relays or translator_class.quick is not Translator.quick)
        )
        self._countdown = EXPRESS_SAMPLE  # messages to the next one left to the full path
        self._owed = 0  # messages the express path carried that the inline budget has not been charged

    def offer(self, received: Received) -> None:
        """Called on the transport's thread: keep the message if this route's source matches, and
        translate it right here when the route is idle and the thread's budget allows (else the
        worker does). Once per message on every route: kept to few calls (`_translated_inline`
        written out here), each of which costs as much as a small message's translation."""
        match = self.pattern.fullmatch(received.channel)
        if match is None:
            return
        stats = self.stats
        stats.messages_in += 1
        stats.bytes_in += len(received.data)
        message = Message(received, match)
        inline = self._inline
        if inline is not None and not self.mailbox.waiting:
            started = time.perf_counter()
            quick = self._keeps_every and self._cost_s < QUICK_S
            if (quick or inline.allows(started)) and self._turn.acquire(False):
                try:
                    self.handle(message)
                finally:
                    self._turn.release()
                    # this message, and as many again as the express path carried since the last
                    owed, self._owed = self._owed, 0
                    inline.spent(started, time.perf_counter(), 1 + owed)
                return
        self.mailbox.put(message)

    def came_back(self, received: Received, origin: tuple[str, str]) -> None:
        """A message the bridge itself sent, come back (the loop guard, `viewer_bridge.router.echoes`)
        from `origin` (transport, channel) where it first came from: held (`own_message`) when this
        route would send it back there, else offered as any other."""
        match = self.pattern.fullmatch(received.channel)
        if match is None:
            return
        try:
            back_where = (
                self.route.destination.transport,
                destination_name(self.route.destination.name, match, self._names, self.commands),
            )
        except Exception:  # a name the template cannot make: offered, and counted where it is made
            back_where = None
        if back_where != origin:
            if len(self._own_channels) < MAX_HELD_CHANNELS:  # bounded: a flood of names is not kept
                self._own_channels.add(received.channel)
            self.offer(received)  # a copy elsewhere (LCM X -> /lcm/X beside /lcm_in/X -> X): no loop
            return
        self.stats.messages_in += 1
        self.stats.bytes_in += len(received.data)
        self._count_held(
            received.channel, Held("own_message", "the bridge's own message, come back: not sent again")
        )

    def express(self, channel: str) -> Express | None:
        """This route's express path for `channel`, when it is the channel's only route
        (`Transport.offer_express`), or None while it has none: a function of a message's bytes
        that translates (`Translator.quick`, or the bytes as they are) and publishes on the
        transport's thread with none of the full path's calls (no `Received`, no `Message`, no
        clock per message but a lazy route's, no stats sample), and says False when the message
        must take the full path: the route busy (its worker has messages, or holds its turn), a
        message over `EXPRESS_MAX_BYTES`, a lazy route with nobody listening (asked here when due,
        as the full path asks) or messages kept for when someone does, a type or an output it has
        not seen, anything raised (the full path does it again and
        counts it), or one message in `EXPRESS_SAMPLE`, which the full path times for the stats
        and the inline budget. Made once a lane has publishers (its stream's first message took
        the full path), again when it has more."""
        if not self._expressible:
            return None
        match = self.pattern.fullmatch(channel)
        lane = None if match is None else self._lanes.get(match.groups())
        if lane is None or lane.reclaimed or not lane.made:
            return None
        if lane.express is None or lane.express_made != len(lane.made):
            lane.express, lane.express_made = self._express_lane(lane), len(lane.made)
        return lane.express

    def _express_lane(self, lane: _Lane) -> Express | None:
        """`lane`'s express path over the publishers it has now, or None when one of them is
        guarded against echoes (it reads the message's channel, which this path does not set)."""
        publishers: dict[int, Publisher] = {}
        for index, (output, publisher) in lane.made.items():
            if isinstance(publisher, GuardedPublisher) or output is not lane.translator.outputs[index]:
                return None
            publishers[index] = publisher
        translator = lane.translator
        quick = None if translator.relays else translator.quick
        # One output for most messages (a relay's, or `Translator.direct`'s): its publisher fixed
        # here, the payload made by one call (or none), with no tuple made and none looked up.
        make: Callable[[bytes], bytes | None] | None = None
        if quick is None:
            fixed = publishers.get(0)
            if fixed is None:
                return None
        else:
            direct = translator.direct()
            fixed = None if direct is None else publishers.get(direct[0])
            if direct is not None and fixed is not None:  # else `quick` finds the output has none
                make = direct[1]
        stats, mailbox, turn, lazy, monotonic = (
            self.stats,
            self.mailbox,
            self._turn,
            self._lazy,
            time.monotonic,
        )

        def carry(data: bytes) -> bool:
            # Once per message: every line here is what a small message costs.
            size = len(data)
            if mailbox.waiting or lane.reclaimed or size > EXPRESS_MAX_BYTES:
                return False
            countdown = self._countdown - 1
            if countdown <= 0:  # the sample: the full path times it, and charges the budget for the rest
                self._countdown, self._owed = EXPRESS_SAMPLE, EXPRESS_SAMPLE - 1
                return False
            self._countdown = countdown
            if lazy:
                # Its listeners asked for when due, here, as the full path would ask.
                if monotonic() - lane.checked_at >= _LISTENERS_CHECK_S:
                    try:
                        lane.listened()
                    except Held:  # an output's publisher cannot be made yet: the full path counts it
                        return False
                if lane.skipped or not lane.listened_now:
                    return False
            # Its turn free, the mailbox empty: nothing of this route's is being translated, and only this
            # thread could give its worker more (the worker takes the turn meanwhile only to look
            # at lazy lanes' kept messages, which this lane has none of), so the order holds
            # without taking the turn (a lock's acquire is the dearest call here).
            if turn.locked():
                return False
            try:
                payload = data if quick is None else None if make is None else make(data)
                if payload is not None:
                    publisher = fixed
                else:  # `quick` (or `direct`'s function could not make it)
                    made = quick(data)  # type: ignore[misc]
                    if made is None:
                        return False
                    index, payload = made
                    publisher = publishers.get(index)
                    if publisher is None:
                        return False
                publisher.publish(payload)  # type: ignore[union-attr]
            except Exception:  # the full path translates and publishes it again, and counts what fails
                return False
            lane.used = True
            stats.messages_in += 1
            stats.bytes_in += size
            stats.messages_out += 1
            stats.bytes_out += len(payload)
            return True

        return carry

    def feed(self, received: Received) -> None:
        """Offline (no worker running): translate and publish at once, on the caller's thread, if
        this route's source matches; no mailbox, no rate limit and no age limit (a log's times are
        its own), so every message is translated."""
        self._max_age_us = None
        match = self.pattern.fullmatch(received.channel)
        if match is not None:
            self.stats.messages_in += 1
            self.stats.bytes_in += len(received.data)
            self.handle(Message(received, match))

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
                if period:
                    message = self.mailbox.take()
                    if message is not None:
                        next_due = time.monotonic() + period
                        self.handle(message)
                else:
                    self._drain()

    def _drain(self) -> None:
        """Every message waiting, for one wake-up of the worker: taken one at a time, so the
        mailbox's policy applies to what arrives meanwhile (the newest per channel wins)."""
        while not self._stop.is_set() and (message := self.mailbox.take()) is not None:
            self.handle(message)

    def catch_up(self) -> None:
        """A lazy route's lanes that skipped messages and now have a subscriber translate them."""
        for lane in list(self._lanes.values()):
            try:
                if lane.skipped and lane.listened():
                    self._replay(lane)
            except Held:  # its publisher cannot be made yet: its next message is counted
                continue

    def _replay(self, lane: _Lane) -> None:
        skipped, lane.skipped = lane.skipped, {}
        for message in skipped.values():
            # Kept while nobody listened: how long it waited is no latency of the bridge's.
            self._translate(lane, message, latency=False)

    def _publisher(self, name: str, output: Output) -> Publisher:
        publisher = self._publishers.get((name, output.type))
        if publisher is None:
            publisher = self._publishers[(name, output.type)] = self._publisher_for(name, output)
        return publisher

    def _lane(self, message: Message) -> _Lane:
        key = message.match.groups()
        lane = self._lanes.get(key)
        if lane is None:
            now = self._clock()
            name = destination_name(self.route.destination.name, message.match, self._names, self.commands)
            self._admit(name, message.channel, now)
            translator, self.prototype = self.prototype or self._make_translator(), None
            lane = self._lanes[key] = _Lane(name, translator, self._publisher, message.channel, now)
        return lane

    def admits(self, source_name: str) -> bool:
        """Whether a message on `source_name` could be carried: for a route that writes commands,
        whether its destination is a channel the allow-list names (a source transport subscribes
        to nothing else); True for every other route."""
        match = self.pattern.pattern.fullmatch(source_name)  # not remembered: names of a graph, not messages
        if self.commands is None or match is None:
            return match is not None
        try:
            name = destination_name(self.route.destination.name, match, self._names, self.commands)
            return self.commands.allows(name)
        except Held:
            return False

    def _reclaim(self, now: float) -> None:
        """Let every lane quiet for `stream_idle_s` go, with the publishers no other lane uses (closed,
        so the transport frees them) and its exclusive destination: room for new streams, while
        the route still holds at most `max_streams`. A lane whose publishers cannot free what their
        transport holds stays (`_Lane.closable`): letting it go would leave that state behind."""
        if now < self._reclaim_at:
            return
        idle_s = self.route.stream_idle_s
        for lane in self._lanes.values():  # used since the last scan: used now, as far as a scan can tell
            if lane.used:
                lane.used_at, lane.used = now, False
        quiet = [key for key, lane in self._lanes.items() if now - lane.used_at >= idle_s and lane.closable()]
        gone = [self._lanes.pop(key) for key in quiet]
        for lane in gone:
            lane.reclaimed = True
        kept = {lane.name for lane in self._lanes.values()}
        for lane in gone:
            if self._destinations is not None:
                place = (self.route.destination.transport, lane.name)
                self._destinations.release(place, (self.route.source.transport, lane.channel))
            if lane.name in kept:  # another stream publishes there too: its publishers stay
                continue
            for key in lane.names():
                publisher = self._publishers.pop(key, None)
                if isinstance(publisher, Closable):
                    try:
                        publisher.close()
                    except Exception as error:  # the transport refused: the stream is gone all the same
                        self._error(f"close:{type(error).__name__}", f"{key[0]}: {error}")
            kept.add(lane.name)  # its publishers are closed once, though several lanes had them
        before = self.stats.streams_reclaimed
        self.stats.streams_reclaimed += len(gone)
        if gone and (before == 0 or before // 1000 != self.stats.streams_reclaimed // 1000):  # never a flood
            log.info(
                "route %s: streams quiet for %g s give their lanes to new ones (%d so far; streams_reclaimed)",
                self.route.name,
                idle_s,
                self.stats.streams_reclaimed,
            )
        oldest = min((lane.used_at for lane in self._lanes.values()), default=now)
        self._reclaim_at = max(oldest + idle_s, now + RECLAIM_SCAN_S)

    def _admit(self, name: str, channel: str, now: float) -> None:
        """Raise `Held` when a new stream from `channel` publishing on `name` may not have a lane: a
        command destination not allowed, one stream more than the route's `max_streams` (once the
        streams quiet for `stream_idle_s` have given theirs back), or an exclusive destination
        another stream carries."""
        if self.commands is not None and not self.commands.allows(name):
            raise Held("not_allowed", self.commands.refusal(name))
        if len(self._lanes) >= self.route.max_streams:
            self._reclaim(now)
        if len(self._lanes) >= self.route.max_streams:
            raise Held(
                "too_many_streams",
                f"the route carries {len(self._lanes)} streams already (its max_streams): not carried",
            )
        if self._destinations is not None:
            source, destination = self.route.source, self.route.destination
            owner = self._destinations.claim((destination.transport, name), (source.transport, channel))
            if owner != (source.transport, channel):
                raise Held(
                    "channel_taken",
                    f"{destination.transport} {name} carries {owner[1]} (from {owner[0]}) already: "
                    f"{channel} (from {source.transport}) is not carried there",
                )

    def _expired(self, message: Message) -> Held | None:
        """Why a message is too old to send (older than the route's `max_age_ms` now), or None."""
        if (
            self._max_age_us is None
            or time.time_ns() // 1000 - message.received.sent_at_us() <= self._max_age_us
        ):
            return None
        return Held(
            "stale", f"older than max_age_ms ({self._max_age_us / 1000:g}) when it would be sent: dropped"
        )

    def handle(self, message: Message) -> None:
        """Translate and publish one message; errors are counted and reported, never raised."""
        try:
            lane = self._lanes.get(message.match.groups()) or self._lane(message)
            lane.used = True  # no clock per message: the next reclaim scan dates it
            if lane.observes:
                lane.translator.observe(message.received)
            if self._lazy:
                if not lane.listened():
                    lane.skip(message)
                    self.stats.idle_skipped += 1
                    return
                if lane.skipped:  # a subscriber just appeared: what came before goes first
                    lane.skipped.pop(message.channel, None)
                    self._replay(lane)
        # a type unknown or refused here, an interface being built: counted on its channel
        except Held as held:
            self._held(message, held)
            return
        except Exception as error:  # a bug in a translator's bookkeeping or a transport
            self._error(f"crash:{type(error).__name__}", f"{message.channel}: {traceback.format_exc()}")
            return
        self._translate(lane, message)

    def _translate(self, lane: _Lane, message: Message, latency: bool = True) -> None:
        # Once per message: calls are what a small message costs, so lookups are written out here.
        skipped = current_collector()
        if skipped is None:
            skipped = thread_collector()
        skipped.clear()  # what a translation that raised left there was no part of a message sent
        started = time.perf_counter()
        try:
            outputs = lane.translator.translate(message.received)
        except Held as held:
            self._held(message, held)
            return
        except BridgeError as error:
            self._error(type(error).__name__, f"{message.channel}: {error}")
            self._tell_source(message, error)
            return
        except Exception as error:  # a bug in a translator: report it, keep serving
            self._error(f"crash:{type(error).__name__}", f"{message.channel}: {traceback.format_exc()}")
            return
        spent = time.perf_counter() - started
        stats = self.stats
        stats.translate_ms.append(spent * 1e3)
        self._cost_s += (spent - self._cost_s) * 0.1
        if skipped:
            self._count_skipped(message, skipped)
        if self._max_age_us is not None and (stale := self._expired(message)) is not None:
            self._held(message, stale)  # a command held up (a stall, a busy core) is never sent late
            return
        # Its receive time (what a file stamps its outputs with) and channel (the loop guard's origin).
        self._message_time.message = message.received
        made = lane.made
        for index, payload in outputs:
            try:
                kept = made.get(index)  # its publisher, while the output at `index` is the same
                publisher = (
                    kept[1]
                    if kept is not None and kept[0] is lane.translator.outputs[index]
                    else lane.publisher(index)
                )
                if payload.__class__ is bytes:  # nearly every payload: no ABC check on the hot path
                    publisher.publish(payload)
                else:
                    hand_over(publisher, payload)
            except Held as held:  # its interface is being built: counted on the channel, the rest goes on
                self._held(message, held)
                continue
            except Exception as error:  # the transport refused: count it, go on with the rest
                self._error(f"publish:{type(error).__name__}", f"{lane.name}: {error}")
                continue
            stats.messages_out += 1
            stats.bytes_out += len(payload) if payload.__class__ is bytes else size_of(payload)
        if outputs and latency:
            stats.latency_ms.append((time.time_ns() // 1000 - message.received.received_us) / 1e3)

    def _count_skipped(self, message: Message, skipped: list[Skipped]) -> None:
        """The parts of a translated message left out (the rest of it is sent), counted and let go."""
        parts = skipped.copy()
        skipped.clear()
        for part in parts:
            if isinstance(part, BridgeError):  # a part that failed (one image of an array): an error
                self._error(type(part).__name__, f"{message.channel}: {part}")
            else:  # a geometry a target cannot write: a warning
                self._count(self.stats.warnings, "skipped_geometry", f"{message.channel}: {part}")

    def _held(self, message: Message, held: Held) -> None:
        """A message held back on purpose: counted per channel and kind, said once per both. A
        channel the bridge itself writes (`--ros-topics`' outputs, of LCM types it makes from ROS 2
        types) is its own message however unknown its type: nothing for the user to fix."""
        if held.kind == "unknown_type" and message.channel in self._own_channels:
            held = Held(
                "own_message", f"the bridge's own message (it writes {message.channel}): not copied back"
            )
        self._tell_source(message, held)
        self._count_held(message.channel, held)

    def _count_held(self, channel: str, held: Held) -> None:
        if channel not in self.stats.held and len(self.stats.held) >= MAX_HELD_CHANNELS:
            channel = OTHER_CHANNELS
        self.stats.held.setdefault(channel, Counter())[held.kind] += 1
        if self._said.first(channel, held.kind):
            log.log(
                logging.INFO if held.kind == "own_message" else logging.WARNING,  # by design, not a problem
                "route %s: %s: %s (%s; counted, not said again)",
                self.route.name,
                channel,
                held.reason,
                held.kind,
            )

    def qos_mismatch(self, text: str) -> None:
        """A peer's QoS cannot match one of this route's subscriptions or publishers (`text`, the
        transport's words, begins with the topic): counted as `qos_incompatible`, said once per
        topic. Called on the transport's thread."""
        self.stats.qos_incompatible += 1
        topic = text.split(":", 1)[0]
        if self._said.first(topic, "qos_incompatible"):
            log.warning("route %s: %s (qos_incompatible; counted, not said again)", self.route.name, text)

    def _tell_source(self, message: Message, error: BridgeError) -> None:
        if self._rejected is not None:
            try:
                self._rejected(message.received, error)
            except Exception:  # a transport's answer failing must not stop the route
                log.exception("route %s: telling the sender of %s failed", self.route.name, message.channel)

    def _error(self, kind: str, text: str) -> None:
        self._count(self.stats.errors, kind, text)

    def _count(self, counts: Counter[str], kind: str, text: str) -> None:
        counts[kind] += 1
        self._logged[kind] += 1
        count = self._logged[kind]
        if count <= 5 or count % 1000 == 0:  # the first few, then a reminder: never a flood
            log.warning("route %s: %s (%s #%d)", self.route.name, text.rstrip(), kind, count)

    def state(self) -> str:
        lanes = list(self._lanes.values())  # lanes come and go on the route's thread meanwhile
        if self.route.lazy and lanes and not any(lane.listened_now for lane in lanes):
            return "idle: no subscriber"
        return "active"

    def snapshot(self) -> RouteSnapshot:
        # What the transport could not send, by the route that gave it (the publishers are shared
        # by name within a route only, so each is counted once).
        unsent = sum(publisher.unsent for publisher in list(self._publishers.values()))
        return self.stats.snapshot(self.mailbox, self.state(), unsent)
