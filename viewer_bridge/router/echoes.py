"""The loop guard: a bridge that carries a channel both ways on the same names does not send its
own messages back.

A route that publishes LCM `X` on ROS 2 `/X` and a route that reads ROS 2 `/X` back to LCM `X`
would pass each message round for ever: the bridge's own subscription on `/X` hears its own
publisher, and LCM hears what the bridge sent it. So, for each (transport, name) the router both
publishes on and subscribes to (and only those: elsewhere nothing is wrapped and nothing is
paid), the publisher remembers, for `WINDOW_S` seconds, a digest of each payload it sends and
where that payload's message came from (the route's source transport and channel). The first
message that arrives on that name with the same payload is the bridge's own: a route that would
send it back where it came from holds it (counted as `own_message`); any other route (a copy
under another name, `/lcm/X` beside `/lcm_in/X`) takes it as usual. Consume-once: each send
matches one message, so a genuine identical message from another node within the window costs
at most the one that was matched, never every copy. The transports need nothing for it: the
router sees names and bytes.

The digest is Python's `hash` of the bytes (SipHash, 64 bits, salted per process): identical
payloads match, and two different ones sharing a digest within a window are not to be met.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from viewer_bridge.shared import MessageTime
from viewer_bridge.transports.base import Closable, Deliver, Publisher, Received

WINDOW_S = 2.0  # how long a sent payload is waited for: a round trip through one bus, with room
LIMIT = 10_000  # sends remembered per name at most: a flood forgets its oldest, memory never grows

Origin = tuple[str, str]  # (transport, channel) a message came from
CameBack = Callable[[Received, Origin], None]


class EchoGuard:
    """The payloads sent on one name and not yet heard back, with where each came from."""

    __slots__ = ("_order", "_pending", "_lock", "_window")

    def __init__(self, window: float = WINDOW_S) -> None:
        self._order: deque[tuple[float, int]] = deque()  # (expiry, digest) of every send, oldest first
        self._pending: dict[int, deque[tuple[float, Origin]]] = {}  # digest -> its sends not heard back
        self._lock = threading.Lock()
        self._window = window

    def sent(self, data: bytes, origin: Origin) -> int:
        """Remember `data` as sent now for a message from `origin`; its digest (for `unsent`)."""
        digest = hash(data)
        now = time.monotonic()
        expiry = now + self._window
        with self._lock:
            order = self._order
            if order and order[0][0] <= now:
                self._expire(now)
            if len(order) >= LIMIT:  # a flood: forget the oldest send
                self._forget(*order.popleft())
            order.append((expiry, digest))
            sends = self._pending.get(digest)
            if sends is None:
                sends = self._pending[digest] = deque()
            sends.append((expiry, origin))
        return digest

    def unsent(self, digest: int) -> None:
        """A send that failed: nothing will come back for it."""
        with self._lock:
            sends = self._pending.get(digest)
            if sends:
                sends.pop()
                if not sends:
                    del self._pending[digest]

    def origin(self, message: Received) -> Origin | None:
        """Where `message` first came from when it is one the bridge sent (that send is then
        consumed), else None. Once per message: asked through `message.decoded`, so every route
        offered the message gets the same answer."""
        return message.decoded(self._judge)

    def _judge(self, message: Received) -> Origin | None:
        digest = hash(message.data)
        now = time.monotonic()
        with self._lock:
            if self._order and self._order[0][0] <= now:
                self._expire(now)
            sends = self._pending.get(digest)
            if not sends:
                return None
            _, origin = sends.popleft()
            if not sends:
                del self._pending[digest]
            return origin

    def _expire(self, now: float) -> None:  # the caller holds the lock
        order = self._order
        while order and order[0][0] <= now:
            self._forget(*order.popleft())

    def _forget(self, expiry: float, digest: int) -> None:
        """The send of `digest` due to expire at `expiry`, unless it was heard back already."""
        sends = self._pending.get(digest)
        if sends and sends[0][0] <= expiry:
            sends.popleft()
            if not sends:
                del self._pending[digest]


class GuardedPublisher:
    """A publisher whose payloads its name's guard remembers, with their origin, before they go."""

    __slots__ = ("_publisher", "_guard", "_transport", "_sending")

    def __init__(self, publisher: Publisher, guard: EchoGuard, transport: str, sending: MessageTime) -> None:
        self._publisher = publisher
        self._guard = guard
        self._transport = transport  # the route's source transport
        self._sending = sending  # the channel of the message whose outputs this thread publishes

    @property
    def unsent(self) -> int:
        return self._publisher.unsent

    @unsent.setter
    def unsent(self, count: int) -> None:
        self._publisher.unsent = count

    def publish(self, data: bytes) -> None:
        # Remembered before the send: the echo may come back before publish returns.
        digest = self._guard.sent(data, (self._transport, self._sending.channel))
        try:
            self._publisher.publish(data)
        except BaseException:
            self._guard.unsent(digest)
            raise

    def subscriber_count(self) -> int | None:
        return self._publisher.subscriber_count()


class ClosingGuardedPublisher(GuardedPublisher):
    """A guarded publisher whose own publisher is `Closable`: so is it."""

    __slots__ = ()

    def close(self) -> None:
        assert isinstance(self._publisher, Closable)
        self._publisher.close()


class Echoes:
    """The router's guards, by transport and name, made when a publisher is made on a name the
    router also subscribes to."""

    def __init__(self, sending: MessageTime, window: float = WINDOW_S) -> None:
        self._guards: dict[str, dict[str, EchoGuard]] = {}  # transport -> name -> guard
        self._lock = threading.Lock()
        self._sending = sending
        self._window = window

    def publisher(
        self, transport: str, name: str, publisher: Publisher, source: str, subscribed: bool
    ) -> Publisher:
        """`publisher` on `name` of `transport` for a route reading `source` (a transport),
        guarded when the router also subscribes to that name there."""
        if not subscribed:
            return publisher
        with self._lock:
            names = self._guards.setdefault(transport, {})
            guard = names.get(name)
            if guard is None:
                guard = names[name] = EchoGuard(self._window)
        kind = ClosingGuardedPublisher if isinstance(publisher, Closable) else GuardedPublisher
        return kind(publisher, guard, source, self._sending)

    def deliver(self, transport: str, offer: Deliver, came_back: CameBack, published: bool = True) -> Deliver:
        """What a route's subscription on `transport` calls: `came_back` for the bridge's own
        messages coming back (with where they first came from), `offer` for every other.
        `published`: whether any route publishes on `transport`; when none does, nothing of the
        bridge's can come back there, and `offer` itself is what is called (a call less a message)."""
        if not published:
            return offer
        with self._lock:
            guards = self._guards.setdefault(transport, {})  # filled later, as publishers are made

        def deliver(message: Received) -> None:
            guard = guards.get(message.channel) if guards else None
            origin = None if guard is None else guard.origin(message)
            if origin is None:
                offer(message)
            else:
                came_back(message, origin)

        return deliver
