"""What the Zenoh transport declares on its session: publishers, subscriptions, and the graph.

A ROS 2 publisher is a Zenoh publisher on the topic's data key, a liveliness token that tells
rmw_zenoh's graph about it, and the 33-byte attachment on every sample (docs/PROTOCOLS.md
section 10). A latched one (TRANSIENT_LOCAL) is what rmw_zenoh's Jazzy release makes of it: an
advanced publisher with a cache of `depth` samples that announces itself, so that a subscriber
that starts later, with history and late-publisher detection, queries the cache. LCM channels
are plain publishers under a key prefix, without tokens or attachments; latched, the last
message of every channel is kept in one `LastValues` queryable, which a subscriber that joins
later asks once (zenoh-ext's per-publisher caches answer a wildcard query for only some of many
channels of one session: seen with eclipse-zenoh 1.10).

`Graph` follows the ROS graph's tokens: how many subscribers a topic has (what `lazy` routes
ask), and which topics have publishers (what a source regex is matched against).
"""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Callable

import zenoh
import zenoh.ext

from viewer_bridge.errors import DecodeError
from viewer_bridge.transports.base import Deliver, MessageType, Qos, Received
from viewer_bridge.transports.ros_qos import Offered
from viewer_bridge.transports.zenoh import keys
from viewer_bridge.transports.zenoh.session import Link

Errors = Counter[str]  # the transport's own error counts by kind, shared by what it declares


def declare_put(session: zenoh.Session, key: str, qos: Qos) -> Callable[..., None]:
    """The `put` of a publisher on `key`: a cached, self-announcing one when latched."""
    reliability = zenoh.Reliability.RELIABLE if qos.reliable else zenoh.Reliability.BEST_EFFORT
    if qos.latched:
        cached = zenoh.ext.declare_advanced_publisher(
            session,
            key,
            congestion_control=zenoh.CongestionControl.DROP,
            reliability=reliability,
            cache=zenoh.ext.CacheConfig(qos.depth),
            publisher_detection=True,
        )
        return cached.put
    plain = session.declare_publisher(
        key, congestion_control=zenoh.CongestionControl.DROP, reliability=reliability
    )
    return plain.put


class Matching:
    """Whether any Zenoh subscriber matches a key (a plain publisher declared only to ask)."""

    def __init__(self, link: Link, key: str) -> None:
        self.matching = False

        def declare(session: zenoh.Session) -> None:
            asker = session.declare_publisher(key)
            link.hold(asker)
            link.hold(asker.declare_matching_listener(link.calling(self._changed)))

        link.when_open(declare)

    def _changed(self, status: zenoh.MatchingStatus) -> None:
        self.matching = status.matching


class LastValues:
    """The last message of each latched LCM channel, answering queries on `<prefix>/**`."""

    def __init__(self, link: Link, prefix: str) -> None:
        self.values: dict[str, bytes] = {}  # key -> payload; a dict store per message

        def declare(session: zenoh.Session) -> None:
            link.hold(session.declare_queryable(f"{prefix}/**", link.calling(self._answer)))

        link.when_open(declare)

    def _answer(self, query: zenoh.Query) -> None:
        asked = query.key_expr
        for key, payload in list(self.values.items()):
            if asked.intersects(zenoh.KeyExpr(key)):
                query.reply(key, payload)


def ask_last_values(session: zenoh.Session, prefix: str, on_sample: Callable[[zenoh.Sample], None]) -> None:
    """Every `LastValues` on the network, asked once: their replies go to `on_sample`."""

    def on_reply(reply: zenoh.Reply) -> None:
        if reply.ok is not None:
            on_sample(reply.ok)

    session.get(f"{prefix}/**", on_reply, target=zenoh.QueryTarget.ALL)


class LcmPublisher:
    """Raw bytes on `<prefix>/<channel>`; the subscriber count is 1 while any subscriber matches.
    With `last`, the last message is kept there too, for subscribers that join later."""

    __slots__ = ("_put", "_link", "_matching", "_key", "_last", "unsent")

    def __init__(self, link: Link, key: str, qos: Qos, last: LastValues | None) -> None:
        self._put: Callable[..., None] | None = None
        self._link = link
        self._matching = Matching(link, key)
        self._key = key
        self._last = None if last is None else last.values
        self.unsent = 0  # published while no router (or peer) was connected

        def declare(session: zenoh.Session) -> None:
            self._put = link.putting(declare_put(session, key, Qos(qos.depth, qos.reliable)))

        link.when_open(declare)

    def publish(self, data: bytes) -> None:
        if self._last is not None:
            self._last[self._key] = data
        put = self._put
        if put is None or not self._link.connected:
            self.unsent += 1
            if put is None:
                return
        put(data)

    def subscriber_count(self) -> int:
        return int(self._matching.matching)


class RosPublisher:
    """CDR on a topic's data key, with its token and the attachment rmw_zenoh reads."""

    __slots__ = ("_put", "_link", "_gid", "_sequence", "_graph", "_topic", "_matching", "unsent")

    def __init__(
        self, link: Link, graph: Graph, key: str, token: Callable[[str], keys.Token], qos: Qos
    ) -> None:
        self._put: Callable[..., None] | None = None
        self._link = link
        self._gid = bytes(16)
        self._sequence = 0
        self._graph = graph
        self._topic: keys.TopicEntity | None = None
        self._matching = Matching(link, key)
        self.unsent = 0

        def declare(session: zenoh.Session) -> None:
            declared = token(str(session.zid()))
            self._topic = declared.topic
            self._gid = keys.gid(declared.key())
            self._put = link.putting(declare_put(session, key, qos))
            link.hold(session.liveliness().declare_token(declared.key()))

        link.when_open(declare)

    def publish(self, data: bytes) -> None:
        put = self._put
        if put is None or not self._link.connected:
            self.unsent += 1
            if put is None:
                return
        self._sequence += 1
        put(data, keys.ATTACHMENT.pack(self._sequence, time.time_ns(), 16, self._gid))

    def subscriber_count(self) -> int:
        """rmw_zenoh subscribers by their tokens; else 1 while any Zenoh subscriber matches."""
        topic = self._topic
        tokens = 0 if topic is None else self._graph.subscribers(topic.topic, topic.dds_type)
        return tokens or int(self._matching.matching)


def declare_subscriber(
    session: zenoh.Session, key: str, qos: Qos, on_sample: Callable[[zenoh.Sample], None]
) -> object:
    """A subscriber on `key`; when latched, one that asks publishers' caches for their history,
    and for that of publishers that appear later."""
    if qos.latched:
        history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=qos.depth)
        return zenoh.ext.declare_advanced_subscriber(
            session, key, on_sample, history=history, subscriber_detection=True
        )
    return session.declare_subscriber(key, on_sample)


def ros_receiver(
    channel: str, message_type: MessageType, delivers: list[Deliver], errors: Errors
) -> Callable[[zenoh.Sample], None]:
    """A sample callback: checks the key (concrete, no wildcard), the attachment and the CDR
    header, then hands the payload (of `message_type`) to every route reading the topic. What
    fails a check is counted and dropped."""

    def on_sample(sample: zenoh.Sample) -> None:
        if keys.wildcard(str(sample.key_expr)):
            errors["wildcard_key"] += 1
            return
        attachment = sample.attachment
        try:
            stamp = keys.parse_attachment(b"" if attachment is None else attachment.to_bytes())
        except DecodeError:
            errors["bad_attachment"] += 1
            return
        payload = sample.payload.to_bytes()
        if not is_cdr(payload):
            errors["not_cdr"] += 1
            return
        # The sender's clock at publish (rmw_zenoh's source timestamp): what a command's age counts from.
        sent_us = stamp.timestamp_ns // 1000 if stamp.timestamp_ns > 0 else None
        message = Received(channel, payload, message_type=message_type, sent_us=sent_us)
        for deliver in delivers:
            deliver(message)

    return on_sample


def is_cdr(payload: bytes) -> bool:
    """Whether `payload` starts with a plain CDR encapsulation header (big or little endian)."""
    return len(payload) >= 4 and payload[0] == 0 and payload[1] in (0, 1)


class Graph:
    """The ROS graph of one domain as its liveliness tokens tell it."""

    def __init__(self, errors: Errors) -> None:
        self._tokens: dict[str, keys.Token] = {}
        self._subscribers: Counter[tuple[str, str]] = Counter()
        self._errors = errors
        self._lock = threading.Lock()

    def on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        with self._lock:
            if sample.kind == zenoh.SampleKind.PUT:
                try:
                    token = self._tokens[key] = keys.parse_token(key)
                except DecodeError:
                    self._errors["bad_token"] += 1
                    return
                self._count(token, 1)
            elif key in self._tokens:
                self._count(self._tokens.pop(key), -1)

    def _count(self, token: keys.Token, step: int) -> None:
        if token.kind == keys.SUBSCRIBER and token.topic is not None:
            self._subscribers[token.topic.topic, token.topic.dds_type] += step

    def subscribers(self, topic: str, dds_type: str) -> int:
        return self._subscribers[topic, dds_type]

    def offered(self, topic: str) -> list[Offered]:
        """What each publisher on `topic` declares in its token (its reliability, durability, depth)."""
        return [
            Offered(
                entity.qos.reliable,
                entity.qos.transient_local,
                0 if entity.qos.keep_all else entity.qos.depth,
            )
            for _, entity in self._publisher_topics()
            if entity.topic == topic
        ]

    def publishers(self) -> set[tuple[str, str, str]]:
        """(topic, DDS type name, type hash) of every publisher the graph knows."""
        return {(topic.topic, topic.dds_type, topic.type_hash) for _, topic in self._publisher_topics()}

    def published_by(self, node: keys.NodeName) -> set[str]:
        """The topics a node of this name and namespace publishes on (a bridge's workers share theirs)."""
        return {
            topic.topic
            for token, topic in self._publisher_topics()
            if (token.node.name, token.node.namespace) == (node.name, node.namespace)
        }

    def _publisher_topics(self) -> list[tuple[keys.Token, keys.TopicEntity]]:
        with self._lock:
            tokens = list(self._tokens.values())
        return [(t, t.topic) for t in tokens if t.kind == keys.PUBLISHER and t.topic is not None]
