"""foxglove-sdk's subscribe race, provoked on the installed SDK's own server.

The SDK sends a client the `advertise` of a new channel, then lists the channel as that client's;
a subscription that arrives in between is refused with the status `Unknown channel ID: N` and
dropped (viewer_bridge/transports/foxglove_front.py, `Resubscriptions`, says where in its code).
On a quiet machine the thread making the channel finishes both steps long before a client can
answer, so the race shows only under load. `making_channels` brings the load on deterministically
enough: the thread that makes the channels shares one CPU with the SDK's tokio threads (and the
front's, and the client's) and runs under SCHED_IDLE, so the kernel preempts it the moment the
advertise wakes a tokio thread and gives it the CPU back only once nothing else wants it, after
the client's subscription (measured on the SDK alone: about a third of 50 eager subscriptions
refused, none when made on a normal thread). A client in a process of its own must be in this
process's session: the kernel weighs each session as one (autogroup), and a thread of another
session would let the idle thread run beside it.
"""

from __future__ import annotations

import contextlib
import json
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import foxglove
from foxglove.websocket import ChannelView, Client
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect
from websockets.typing import Subprotocol

WAIT = 60.0
UNKNOWN_CHANNEL = "Unknown channel ID: "  # the SDK's words, as a client reads them


def _threads() -> list[int]:
    """The ids of this process's threads."""
    return [int(task.name) for task in Path("/proc/self/task").iterdir()]


@contextlib.contextmanager
def making_channels(make: Callable[[], None], peers: Iterable[int] = ()) -> Iterator[None]:
    """Runs `make` on a thread of its own at SCHED_IDLE, on one CPU with every other thread of
    this process (the SDK's tokio threads, the front's) and the threads `peers` (a client in a
    process of its own): any of them that has work to do runs before it. Their CPUs are given
    back after."""
    cpu = min(os.sched_getaffinity(0))
    pinned: dict[int, set[int]] = {}
    for thread in [*_threads(), *peers]:
        with contextlib.suppress(OSError):  # a thread that has ended meanwhile
            pinned[thread] = os.sched_getaffinity(thread)
            os.sched_setaffinity(thread, {cpu})

    def idle() -> None:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))  # 0: this thread
        make()

    maker = threading.Thread(target=idle, name="idle channel maker", daemon=True)
    maker.start()  # pinned as the thread that starts it is
    try:
        yield
    finally:
        maker.join(WAIT)
        for thread, cpus in pinned.items():
            with contextlib.suppress(OSError):
                os.sched_setaffinity(thread, cpus)


class Subscribers:
    """A server listener keeping the channels the SDK took a subscription of (its `on_subscribe`
    is called only for subscriptions it did not refuse)."""

    def __init__(self) -> None:
        self.topics: set[str] = set()
        self._lock = threading.Lock()

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        with self._lock:
            self.topics.add(channel.topic)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        pass  # the channels taken stay counted: what matters is whether the SDK took them at all

    def subscribed(self) -> set[str]:
        with self._lock:
            return set(self.topics)


class EagerClient:
    """A Foxglove client that subscribes to each channel the moment its advertise arrives, as
    Foxglove's app does, and never subscribes again on its own. It keeps the channels advertised
    and the statuses received."""

    def __init__(self, port: int, subprotocol: str = "foxglove.sdk.v1") -> None:
        self._ws = connect(f"ws://127.0.0.1:{port}", subprotocols=[Subprotocol(subprotocol)],
                           open_timeout=WAIT, ping_interval=None, max_queue=None).__enter__()  # fmt: skip
        self.advertised: dict[int, str] = {}  # channel id -> topic
        self.statuses: list[dict[str, object]] = []
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        with contextlib.suppress(ConnectionClosed):
            for frame in self._ws:
                if not isinstance(frame, str):
                    continue
                message = json.loads(frame)
                if message["op"] == "advertise":
                    entries = [{"id": 1000 + c["id"], "channelId": c["id"]} for c in message["channels"]]
                    self._ws.send(json.dumps({"op": "subscribe", "subscriptions": entries}))
                    with self._lock:
                        self.advertised.update({c["id"]: c["topic"] for c in message["channels"]})
                elif message["op"] == "status":
                    with self._lock:
                        self.statuses.append(message)

    def refused(self) -> list[str]:
        """The topics of channels advertised to this client whose subscription the SDK refused."""
        with self._lock:
            said = [str(status["message"]) for status in self.statuses]
            return [
                topic for channel, topic in self.advertised.items() if f"{UNKNOWN_CHANNEL}{channel}" in said
            ]

    def close(self) -> None:
        self._ws.close()
        self._reader.join(WAIT)


class ChannelMaker:
    """Makes `count` channels on `context`, one every 20 ms (call it, on `making_channels`' thread)."""

    def __init__(self, context: foxglove.Context, count: int, prefix: str = "/race") -> None:
        self.topics = {f"{prefix}/{index}" for index in range(count)}
        self._context = context
        self._made: list[foxglove.Channel] = []  # kept open: a channel dropped is unadvertised

    def __call__(self) -> None:
        for topic in sorted(self.topics):
            self._made.append(foxglove.Channel(topic, message_encoding="json", context=self._context))
            time.sleep(0.02)
