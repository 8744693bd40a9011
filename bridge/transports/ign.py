"""ign-transport 11 as a transport, in Python: UDP multicast discovery plus ZeroMQ data.

No Python binding of ign-transport exists, so this node speaks its wire protocol (docs/PROTOCOLS.md
section 4, checked against Debian's `ign-transport-topic`):

* Discovery: datagrams `[uint16 length, little-endian][ignition.msgs.Discovery]` on
  239.255.0.7:10317, wire version 10. Every second the node sends HEARTBEAT and re-ADVERTISEs
  what it publishes; a peer silent for 3 s is forgotten. It answers SUBSCRIBE with ADVERTISE, and
  when a publisher it wants advertises, it connects and announces itself with NEW_CONNECTION
  (a C++ publisher sends nothing to a subscriber that has not). UNADVERTISE and BYE on close.
* Data: one ZMQ PUB socket bound on `IGN_IP`; a message is four frames: the full topic name
  `@/<partition>@<topic>`, the publisher's address, the serialized protobuf, the type name.

Bytes in, bytes out, like the other transports: what the payload means is the formats' business.
Bad datagrams and frames are counted in `errors` and skipped, with a log line at a bounded rate.
`IgnTransport` is the router's view of a node.
"""

from __future__ import annotations

import getpass
import logging
import os
import queue
import re
import socket
import struct
import threading
import time
import uuid
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import zmq
from google.protobuf.message import DecodeError as ProtobufDecodeError

from bridge.formats.ign.schema import IGNITION
from bridge.transports.base import (
    PROTOBUF,
    CallPublisher,
    Deliver,
    MessageType,
    Publisher,
    Qos,
    Received,
    Transport,
    TransportSettings,
)

log = logging.getLogger("viewer_bridge")

DISCOVERY_GROUP = "239.255.0.7"
MESSAGE_PORT = 10317
SERVICE_PORT = 10318
WIRE_VERSION = 10
HEARTBEAT_S = 1.0
SILENCE_S = 3.0
ANY_TYPE = "google.protobuf.Message"

Discovery = IGNITION.Discovery
ADVERTISE, SUBSCRIBE, UNADVERTISE, HEARTBEAT, BYE, NEW_CONNECTION, END_CONNECTION = 1, 2, 3, 4, 5, 6, 7
Callback = Callable[[str, bytes, int], None]  # topic, serialized protobuf, receive time in microseconds


def default_partition() -> str:
    """`IGN_PARTITION`, or `hostname:username` as ign-transport makes it."""
    return os.environ.get("IGN_PARTITION") or f"{socket.gethostname()}:{getpass.getuser()}"


@dataclass
class _Remote:
    """A publisher this node subscribes to, as its ADVERTISE described it."""

    topic: str
    address: str
    process_uuid: str
    node_uuid: str
    msg_type: str


@dataclass
class _Subscription:
    topic: str  # full name, @/partition@/topic
    msg_type: str
    callbacks: list[Callback] = field(default_factory=list)


class IgnNode:
    """One ign-transport node: advertise/publish and subscribe to topics; thread-safe."""

    def __init__(self, partition: str | None = None, ip: str | None = None) -> None:
        self.partition = partition if partition is not None else default_partition()
        self.ip = ip or os.environ.get("IGN_IP") or "127.0.0.1"
        self.process_uuid = str(uuid.uuid4())
        self.node_uuid = str(uuid.uuid4())
        self.errors: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._context = zmq.Context()
        self._publisher = self._context.socket(zmq.PUB)
        self._publisher.setsockopt(zmq.LINGER, 0)
        self._publisher.bind(f"tcp://{self.ip}:*")
        self.address = self._publisher.getsockopt_string(zmq.LAST_ENDPOINT)
        self._subscriber = self._context.socket(zmq.SUB)
        self._subscriber.setsockopt(zmq.LINGER, 0)
        self._advertised: dict[str, str] = {}  # full topic -> type
        self._subscriptions: dict[str, _Subscription] = {}
        self._remotes: dict[tuple[str, str], _Remote] = {}  # (process uuid, topic) -> publisher
        self._connected: set[str] = set()  # addresses the SUB socket is connected to
        self._last_seen: dict[str, float] = {}
        self._logged: Counter[str] = Counter()
        self._discovery = self._discovery_socket()
        self._pending: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ign-transport", daemon=True)

    # --- the API -----------------------------------------------------------------------------------

    def full_name(self, topic: str) -> str:
        return f"@/{self.partition}@{topic if topic.startswith('/') else '/' + topic}"

    def start(self) -> None:
        self._thread.start()

    def advertise(self, topic: str, msg_type: str) -> None:
        full = self.full_name(topic)
        with self._lock:
            self._advertised[full] = msg_type
        self._send(self._publisher_record(ADVERTISE, full, msg_type))

    def publish(self, topic: str, data: bytes, msg_type: str) -> None:
        full = self.full_name(topic)
        if full not in self._advertised:
            self.advertise(topic, msg_type)
        frames = [full.encode(), self.address.encode(), data, msg_type.encode()]
        with self._lock:  # a ZMQ socket is not thread-safe
            self._publisher.send_multipart(frames)

    def subscribe(self, topic: str, msg_type: str, callback: Callback) -> None:
        full = self.full_name(topic)
        with self._lock:
            subscription = self._subscriptions.setdefault(full, _Subscription(full, msg_type))
            subscription.callbacks.append(callback)
        # The SUB socket belongs to the node's thread (ZMQ sockets are not thread-safe).
        self._pending.put(lambda: self._subscriber.setsockopt(zmq.SUBSCRIBE, full.encode()))
        self._send_subscribe(full)

    def close(self) -> None:
        """UNADVERTISE every topic, END_CONNECTION to every publisher, BYE; then close."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)
        for full, msg_type in list(self._advertised.items()):
            self._send(self._publisher_record(UNADVERTISE, full, msg_type))
        for remote in list(self._remotes.values()):
            self._send(self._connection_record(END_CONNECTION, remote))
        self._send(self._header(BYE))
        self._discovery.close()
        self._publisher.close()
        self._subscriber.close()
        self._context.term()

    # --- discovery -----------------------------------------------------------------------------------

    def _discovery_socket(self) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        sock.bind(("", MESSAGE_PORT))
        membership = socket.inet_aton(DISCOVERY_GROUP) + socket.inet_aton(self.ip)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(self.ip))
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
        sock.setblocking(False)
        return sock

    def _header(self, kind: int) -> object:
        return Discovery(version=WIRE_VERSION, process_uuid=self.process_uuid, type=kind)

    def _publisher_record(self, kind: int, full: str, msg_type: str) -> object:
        message = self._header(kind)
        publisher = message.pub  # type: ignore[attr-defined]
        publisher.topic, publisher.address = full, self.address
        publisher.process_uuid, publisher.node_uuid = self.process_uuid, self.node_uuid
        publisher.scope = 2  # ALL
        publisher.msg_pub.ctrl = ""
        publisher.msg_pub.msg_type = msg_type
        return message

    def _connection_record(self, kind: int, remote: _Remote) -> object:
        """NEW_CONNECTION / END_CONNECTION: the publisher's record, with our uuids."""
        message = self._header(kind)
        publisher = message.pub  # type: ignore[attr-defined]
        publisher.topic, publisher.address = remote.topic, remote.address
        publisher.process_uuid, publisher.node_uuid = self.process_uuid, self.node_uuid
        publisher.scope = 2
        publisher.msg_pub.ctrl = remote.process_uuid
        publisher.msg_pub.msg_type = remote.msg_type
        return message

    def _send_subscribe(self, full: str) -> None:
        message = self._header(SUBSCRIBE)
        message.sub.topic = full  # type: ignore[attr-defined]
        self._send(message)

    def _send(self, message: object, port: int = MESSAGE_PORT) -> None:
        body = message.SerializeToString()  # type: ignore[attr-defined]
        try:
            self._discovery.sendto(struct.pack("<H", len(body)) + body, (DISCOVERY_GROUP, port))
        except OSError as error:
            self._error("send", f"discovery datagram not sent: {error}")

    def _on_datagram(self, data: bytes) -> None:
        if len(data) < 2 or struct.unpack_from("<H", data)[0] + 2 != len(data):
            self._error("discovery_length", f"datagram of {len(data)} bytes: its length prefix disagrees")
            return
        message = Discovery()
        try:
            message.ParseFromString(data[2:])
        except ProtobufDecodeError as error:
            self._error("discovery_parse", f"discovery datagram does not parse: {error}")
            return
        if message.version != WIRE_VERSION:
            self._error("discovery_version", f"discovery wire version {message.version}, not {WIRE_VERSION}")
            return
        if message.process_uuid == self.process_uuid:
            return  # our own, looped back
        self._last_seen[message.process_uuid] = time.monotonic()
        handlers = {ADVERTISE: self._on_advertise, SUBSCRIBE: self._on_subscribe,
                    UNADVERTISE: self._on_unadvertise, BYE: self._on_bye}  # fmt: skip
        handler = handlers.get(message.type)
        if handler is not None:
            handler(message)

    def _on_advertise(self, message: object) -> None:
        publisher = message.pub  # type: ignore[attr-defined]
        with self._lock:
            subscription = self._subscriptions.get(publisher.topic)
        if subscription is None or not publisher.address:
            return
        msg_type = publisher.msg_pub.msg_type
        if subscription.msg_type not in (ANY_TYPE, msg_type):
            self._error("type_mismatch", f"{publisher.topic} is {msg_type}, not {subscription.msg_type}")
            return
        key = (message.process_uuid, publisher.topic)  # type: ignore[attr-defined]
        if key in self._remotes:
            return
        if not _is_tcp_address(publisher.address):  # ZMQ would raise, and end this node's thread
            self._error("advertise_address", f"{publisher.topic}: not a tcp://host:port: {publisher.address[:80]!r}")
            return
        remote = _Remote(
            publisher.topic, publisher.address, publisher.process_uuid, publisher.node_uuid, msg_type
        )
        if remote.address not in self._connected:
            try:
                self._subscriber.connect(remote.address)
            except zmq.ZMQError as error:  # whatever else ZMQ refuses: counted, the node goes on
                self._error("advertise_address", f"{publisher.topic}: {remote.address[:80]!r}: {error}")
                return
            self._connected.add(remote.address)
        self._remotes[key] = remote
        self._send(self._connection_record(NEW_CONNECTION, remote))

    def _on_subscribe(self, message: object) -> None:
        topic = message.sub.topic  # type: ignore[attr-defined]
        msg_type = self._advertised.get(topic)
        if msg_type is not None:
            self._send(self._publisher_record(ADVERTISE, topic, msg_type))

    def _on_unadvertise(self, message: object) -> None:
        self._forget(message.process_uuid, message.pub.topic)  # type: ignore[attr-defined]

    def _on_bye(self, message: object) -> None:
        self._forget(message.process_uuid)  # type: ignore[attr-defined]

    def _forget(self, process_uuid: str, topic: str | None = None) -> None:
        for key in [key for key in self._remotes if key[0] == process_uuid and topic in (None, key[1])]:
            self._remotes.pop(key)
            # The SUB socket stays connected to the address: disconnecting while a peer's pipe
            # is closing trips an assertion in libzmq, and a dead endpoint costs nothing.
        if topic is None:
            self._last_seen.pop(process_uuid, None)

    # --- the loop ------------------------------------------------------------------------------------

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self._discovery, zmq.POLLIN)
        poller.register(self._subscriber, zmq.POLLIN)
        next_beat = 0.0
        while not self._stop.is_set():
            while not self._pending.empty():
                self._pending.get()()
            now = time.monotonic()
            if now >= next_beat:
                next_beat = now + HEARTBEAT_S
                self._beat(now)
            for sock, _ in poller.poll(timeout=100):
                if sock is self._subscriber:
                    self._drain_data()
                else:
                    self._drain_discovery()

    def _beat(self, now: float) -> None:
        self._send(self._header(HEARTBEAT))
        self._send(self._header(HEARTBEAT), SERVICE_PORT)
        for full, msg_type in list(self._advertised.items()):
            self._send(self._publisher_record(ADVERTISE, full, msg_type))
        for full in list(self._subscriptions):
            if not any(key[1] == full for key in self._remotes):
                self._send_subscribe(full)  # until a publisher answers
        for process_uuid, seen in list(self._last_seen.items()):
            if now - seen > SILENCE_S:
                self._forget(process_uuid)

    def _drain_discovery(self) -> None:
        while True:
            try:
                data = self._discovery.recv(65536)
            except BlockingIOError:
                return
            self._on_datagram(data)

    def _drain_data(self) -> None:
        while True:
            try:
                frames = self._subscriber.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            received_us = time.time_ns() // 1000
            if len(frames) != 4:
                self._error("data_frames", f"a ZMQ message of {len(frames)} frames, not 4")
                continue
            topic, _, data, msg_type = frames
            subscription = self._subscriptions.get(topic.decode("utf-8", "replace"))
            if subscription is None:
                self._error("data_topic", f"data for a topic not subscribed: {topic[:80]!r}")
                continue
            type_name = msg_type.decode("utf-8", "replace")
            if subscription.msg_type not in (ANY_TYPE, type_name):
                self._error(
                    "data_type", f"{subscription.topic}: type {type_name[:80]!r}, not {subscription.msg_type}"
                )
                continue
            short = subscription.topic.split("@", 2)[2]
            for callback in subscription.callbacks:
                callback(short, bytes(data), received_us)

    def _error(self, kind: str, text: str) -> None:
        self.errors[kind] += 1
        self._logged[kind] += 1
        if self._logged[kind] <= 5 or self._logged[kind] % 1000 == 0:
            log.warning("ign-transport: %s (%s #%d)", text, kind, self._logged[kind])


_TCP_ADDRESS = re.compile(r"tcp://(?:\[[0-9A-Fa-f:.]+\]|[^\s/:\[\]]+):([0-9]{1,5})")


def _is_tcp_address(address: str) -> bool:
    """What an ign-transport publisher advertises: `tcp://host:port` (IPv6 hosts in brackets)."""
    match = _TCP_ADDRESS.fullmatch(address)
    return match is not None and 0 < int(match.group(1)) < 65536


class IgnSettings(TransportSettings):
    partition: str | None = None  # default: IGN_PARTITION, or hostname:username
    ip: str | None = None  # default: IGN_IP, or 127.0.0.1


_TOPIC = re.compile(r"[A-Za-z0-9_/~-]+")


class IgnTransport(Transport):
    """An `IgnNode` for the router: ign-msgs (`ignition.msgs.*`) or gz-msgs (`gz.msgs.*`) types."""

    Settings = IgnSettings
    encodings = frozenset({PROTOBUF})
    settings: IgnSettings

    def __init__(self, settings: IgnSettings) -> None:
        super().__init__(settings)
        self.node = IgnNode(settings.partition, settings.ip)
        self._delivers: dict[str, list[Deliver]] = {}

    @classmethod
    def carries(cls, message_type: MessageType) -> bool:
        return super().carries(message_type) and message_type.name.startswith(("ignition.msgs.", "gz.msgs."))

    @classmethod
    def check_source(cls, name: str) -> None:
        if not _TOPIC.fullmatch(name):  # ign-transport subscribes by exact topic: a pattern never appears
            raise ValueError(f"an ign source is one topic name, not a pattern: {name!r}")

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        delivers = self._delivers.get(pattern)
        if delivers is not None:  # another route reads this topic already
            delivers.append(deliver)
            return
        delivers = self._delivers[pattern] = [deliver]

        def on_message(topic: str, data: bytes, received_us: int) -> None:
            message = Received(topic, data, received_us)
            for each in delivers:
                each(message)

        self.node.subscribe(pattern, message_type.name, on_message)

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        node, typename = self.node, message_type.name
        node.advertise(name, typename)  # seen by `ign topic -l` from the first message on
        return CallPublisher(lambda data: node.publish(name, data, typename))

    def start(self) -> None:
        self.node.start()

    def describe(self) -> str:
        return f"ign-transport partition {self.node.partition} on {self.node.address}"

    def errors(self) -> Mapping[str, int]:
        return self.node.errors

    def close(self) -> None:
        self.node.close()
