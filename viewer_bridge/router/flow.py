"""How a message waits between a transport's thread and a route's worker, and when it does not.

Each transport delivers on a thread of its own. A route that is idle translates the message
right there, on the transport's thread (`InlineBudget`: no wake-up of another thread, no GIL
hand-off), as long as that thread is not too busy; otherwise the message goes to the route's
worker thread through a `Mailbox`, bounded: with the `latest` policy it keeps the newest message
per channel (a slow consumer gets the newest draw, never a backlog; a draw never displaces a
load, which is on another channel), with `all` a FIFO of `qos.depth` that drops its oldest.
"""

from __future__ import annotations

import re
import threading
from collections import OrderedDict, deque
from dataclasses import dataclass

from viewer_bridge.transports.base import Received


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
        # What the route could not keep up with, by what the user can change: `superseded`, a
        # newer message on its channel came first (`latest`: only the newest matters);
        # `mailbox_full`, the oldest pushed out at `qos.depth` (`all`: a deeper queue, or less load).
        self.superseded = 0
        self.mailbox_full = 0
        # With max_hz, a message superseded while the worker waits out the rate is skipped by
        # design: counted apart from drops (which say the bridge could not keep up).
        self._rate_limited = rate_limited
        self.rate_skipped = 0
        # How many wait, kept by `put` and `take`: what the receiving thread asks of every message
        # (whether to translate inline), read without the lock or a call.
        self.waiting = 0

    @property
    def dropped(self) -> int:
        """Every message lost here for want of time: superseded and pushed out alike."""
        return self.superseded + self.mailbox_full

    def put(self, message: Message) -> None:
        with self._ready:
            if self.keep_latest:
                if self._latest.pop(message.channel, None) is not None:
                    # superseded before it was translated
                    if self._rate_limited:
                        self.rate_skipped += 1
                    else:
                        self.superseded += 1
                self._latest[message.channel] = message
            else:
                if len(self._fifo) >= self._depth:
                    self._fifo.popleft()
                    self.mailbox_full += 1
                self._fifo.append(message)
            self.waiting = len(self._latest) + len(self._fifo)
            self._ready.notify()

    def wait(self, timeout: float) -> bool:
        """Whether a message is waiting, within `timeout` seconds (without taking it)."""
        with self._ready:
            return bool(self._latest or self._fifo or self._ready.wait_for(self.__len__, timeout))

    def take(self) -> Message | None:
        """The next message, or None when there is none (never waits)."""
        with self._ready:
            if self._latest:
                message = self._latest.popitem(last=False)[1]
            elif self._fifo:
                message = self._fifo.popleft()
            else:
                return None
            self.waiting -= 1
            return message

    def __len__(self) -> int:
        return self.waiting


class _Bucket:
    """One receiving thread's inline time: how full its bucket was at `at` (perf_counter seconds)."""

    __slots__ = ("level", "at")

    def __init__(self) -> None:
        self.level = 0.0
        self.at = 0.0


class InlineBudget:
    """Whether a transport's thread may translate a message itself instead of waking a worker.

    Handing a message to a route's worker costs a wake-up and a GIL hand-off between two threads
    per message, which on a loaded core costs more than a quick translation. So the thread that
    received a message translates it at once when the route is idle, as long as that thread has
    spent less than `share` of its recent time translating inline: a leaky bucket per thread, which
    each inline translation fills with its duration and which drains at `share` seconds a second;
    inline while it holds less than `share * window_s` (a burst of that long, then `share` of the
    time). Past that, the workers take over: the mailbox's policy (the newest wins) applies again
    instead of a backlog building up in the transport's receive buffers. A quick `policy: all`
    route asks no budget (`RouteRunner`: it has no newer message to prefer) but fills it.

    The share is 0.9, not the half it was: at 2 kHz of 1000-link draws, translating and publishing
    a draw's routes take more than half of each 0.5 ms period, so at 0.5 many draws went to a
    worker, and each hand-off's wake-up and GIL ping-pong between the two threads held up the
    next draw until it superseded the one waiting. Measured with the same code and machine,
    two runs each: three routes on two workers delivered 53-58% of draws (the least route) at
    0.5 and 99.3-99.6% at 0.9, for the same CPU per draw. The tenth left is what keeps the thread
    reading when translation alone would take all of it.
    """

    def __init__(self, share: float = 0.9, window_s: float = 0.2) -> None:
        self._share = share
        self._capacity = share * window_s
        self._threads = threading.local()  # each receiving thread's own bucket

    def _bucket(self) -> _Bucket:
        try:
            return self._threads.bucket  # type: ignore[no-any-return]
        except AttributeError:
            bucket = self._threads.bucket = _Bucket()
            return bucket

    def allows(self, now: float) -> bool:
        """Whether this thread may translate inline at `now` (time.perf_counter())."""
        bucket = self._bucket()
        return bucket.level - (now - bucket.at) * self._share < self._capacity

    def spent(self, started: float, ended: float, times: float = 1.0) -> None:
        """This thread translated inline from `started` to `ended` (time.perf_counter()), `times`
        times (a sampled message stands for the messages a route's express path carried untimed)."""
        try:  # once per message: no call for the bucket
            bucket = self._threads.bucket
        except AttributeError:
            bucket = self._bucket()
        bucket.level = max(0.0, bucket.level - (ended - bucket.at) * self._share) + (ended - started) * times
        bucket.at = ended
