"""ign/gz-transport as a transport, in Python: UDP multicast discovery plus ZeroMQ data.

No Python binding of ign-transport or gz-transport exists, so this node speaks their wire
protocol, which Fortress (ign-transport 11) and Harmonic and later (gz-transport 13) share
(docs/PROTOCOLS.md sections 4 and 10, checked against Debian's `ign-transport-topic` and a
gz-transport 13 `gz topic`):

* Discovery: `viewer_bridge/transports/ign_discovery.py` says what to send and answer; this node owns
  the UDP socket on the discovery group and port (`GZ_DISCOVERY_*`, see `ign_environment.py`).
* Data: one ZMQ PUB socket bound on `GZ_IP`; a message is four frames: the full topic name
  `@/<partition>@<topic>`, the publisher's address, the serialized protobuf, the type name; with
  topic statistics on (`GZ_TRANSPORT_TOPIC_STATISTICS=1`, wire version 110) a fifth: the
  publication's steady-clock time (ms) and sequence number, two native uint64s.

Which package the type names are in (`gz.msgs.Pose_V`, `ignition.msgs.Pose_V`) is the
transport's `package` setting; a subscription takes either spelling. Bytes in, bytes out, like
the other transports: what the payload means is the formats' business. Bad datagrams and frames
are counted in `errors` and skipped, with a log line at a bounded rate. `IgnTransport` is the
router's view of a node.
"""

from __future__ import annotations

import getpass
import logging
import queue
import re
import socket
import struct
import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping

from viewer_bridge.errors import InvalidName
from viewer_bridge.formats.ign.schema import PACKAGES, Package, type_name, wire_type_name
from viewer_bridge.transports.base import (
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
from viewer_bridge.transports.ign_discovery import HEARTBEAT_S, Callback, Discovery
from viewer_bridge.transports.ign_environment import NodeEnvironment, read_environment
from viewer_bridge.util.extras import missing

try:
    import zmq
except ImportError as error:
    raise missing(error, "the ign transport") from None

log = logging.getLogger("viewer_bridge")

_METADATA = struct.Struct("=QQ")  # a fifth data frame (topic statistics): stamp (ms), sequence number


class IgnNode:
    """One ign/gz-transport node: advertise/publish and subscribe to topics; thread-safe.

    `partition` and `ip` default to the environment's (`GZ_PARTITION`, `GZ_IP`, or their `IGN_`
    names), then to `hostname:username` and 127.0.0.1.
    """

    def __init__(
        self, partition: str | None = None, ip: str | None = None, environment: NodeEnvironment | None = None
    ) -> None:
        environment = read_environment() if environment is None else environment
        self.partition = partition if partition is not None else _partition(environment)
        self.ip = ip or environment.ip or "127.0.0.1"
        self.errors: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._context = zmq.Context()
        self._publisher = self._context.socket(zmq.PUB)
        self._publisher.setsockopt(zmq.LINGER, 0)
        self._publisher.bind(f"tcp://{self.ip}:*")
        self.address = self._publisher.getsockopt_string(zmq.LAST_ENDPOINT)
        self._subscriber = self._context.socket(zmq.SUB)
        self._subscriber.setsockopt(zmq.LINGER, 0)
        self._statistics = environment.topic_statistics
        self._sequence: Counter[str] = Counter()  # per topic, for the statistics frame
        self._logged: Counter[str] = Counter()
        self._discovery_socket = self._open_discovery(environment)
        self.discovery = Discovery(environment, self.address, self._send, self._connect, self._error)
        self._subscriptions = self.discovery.subscriptions
        self._advertised = self.discovery.advertised
        self._pending: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ign-transport", daemon=True)

    # --- the API -----------------------------------------------------------------------------------

    def full_name(self, topic: str) -> str:
        return f"@/{self.partition}@{topic if topic.startswith('/') else '/' + topic}"

    def start(self) -> None:
        self._thread.start()

    def advertise(self, topic: str, msg_type: str) -> None:
        self.discovery.advertise(self.full_name(topic), msg_type)

    def publish(self, topic: str, data: bytes, msg_type: str) -> None:
        full = self.full_name(topic)
        if full not in self._advertised:
            self.advertise(topic, msg_type)
        frames = [full.encode(), self.address.encode(), data, msg_type.encode()]
        with self._lock:  # a ZMQ socket is not thread-safe
            if self._statistics:
                self._sequence[full] += 1
                frames.append(_METADATA.pack(time.monotonic_ns() // 1_000_000, self._sequence[full] - 1))
            self._publisher.send_multipart(frames)

    def subscribe(self, topic: str, msg_type: str, callback: Callback) -> None:
        """`callback` gets every message on `topic` whose type is `msg_type` in either package's
        spelling (any type for `google.protobuf.Message`)."""
        full = self.full_name(topic)
        with self._lock:
            self.discovery.subscribe(full, msg_type).callbacks.append(callback)
        # The SUB socket belongs to the node's thread (ZMQ sockets are not thread-safe).
        self._pending.put(lambda: self._subscriber.setsockopt(zmq.SUBSCRIBE, full.encode()))

    def close(self) -> None:
        """Say goodbye on discovery (UNADVERTISE, END_CONNECTION, BYE); then close."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)
        self.discovery.goodbye()
        self._discovery_socket.close()
        self._publisher.close()
        self._subscriber.close()
        self._context.term()

    # --- sockets -------------------------------------------------------------------------------------

    def _open_discovery(self, environment: NodeEnvironment) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        sock.bind(("", environment.message_port))
        membership = socket.inet_aton(environment.group) + socket.inet_aton(self.ip)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(self.ip))
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
        sock.setblocking(False)
        return sock

    def _send(self, data: bytes, destination: tuple[str, int]) -> None:
        try:
            self._discovery_socket.sendto(data, destination)
        except OSError as error:
            self._error("send", f"discovery datagram not sent to {destination[0]}: {error}")

    def _connect(self, address: str) -> None:
        """Connect the SUB socket (on the node's thread, which reads discovery)."""
        try:
            self._subscriber.connect(address)
        except zmq.ZMQError as error:
            raise OSError(str(error)) from None

    # --- the loop ------------------------------------------------------------------------------------

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self._discovery_socket, zmq.POLLIN)
        poller.register(self._subscriber, zmq.POLLIN)
        next_beat = 0.0
        while not self._stop.is_set():
            while not self._pending.empty():
                self._pending.get()()
            now = time.monotonic()
            if now >= next_beat:
                next_beat = now + HEARTBEAT_S
                self.discovery.beat(now)
            for sock, _ in poller.poll(timeout=100):
                if sock is self._subscriber:
                    self._drain_data()
                else:
                    self._drain_discovery()

    def _drain_discovery(self) -> None:
        while True:
            try:
                data, (sender, _) = self._discovery_socket.recvfrom(65536)
            except BlockingIOError:
                return
            self.discovery.on_datagram(data, sender, time.monotonic())

    def _drain_data(self) -> None:
        while True:
            try:
                frames = self._subscriber.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            received_us = time.time_ns() // 1000
            if len(frames) != 4 and (len(frames) != 5 or len(frames[4]) != _METADATA.size):
                self._error(
                    "data_frames", f"a ZMQ message of {len(frames)} frames, not 4 (5 with statistics)"
                )
                continue
            topic, data, msg_type = frames[0], frames[2], frames[3]
            subscription = self._subscriptions.get(topic.decode("utf-8", "replace"))
            if subscription is None:
                self._error("data_topic", f"data for a topic not subscribed: {topic[:80]!r}")
                continue
            type_name = msg_type.decode("utf-8", "replace")
            if subscription.accepts is not None and type_name not in subscription.accepts:
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


def _partition(environment: NodeEnvironment) -> str:
    """`GZ_PARTITION` (or `IGN_PARTITION`), else `hostname:username` as gz-transport makes it."""
    return environment.partition or f"{socket.gethostname()}:{getpass.getuser()}"


class IgnSettings(TransportSettings):
    partition: str | None = None  # default: GZ_PARTITION (or IGN_PARTITION), or hostname:username
    ip: str | None = None  # default: GZ_IP (or IGN_IP), or 127.0.0.1
    package: Package = "gz"  # the type names' package: gz (Garden to Jetty) or ignition (Fortress)


_TOPIC = re.compile(r"[A-Za-z0-9_/~-]+")
_PACKAGE_PREFIXES = tuple(type_name("", package) for package in PACKAGES)  # "gz.msgs.", ...


class IgnTransport(Transport):
    """An `IgnNode` for the router. A type a translator names by its short name (`Pose_V`) goes on
    the wire in the `package` setting's spelling; a full name (a route's `package` option) as it is."""

    Settings = IgnSettings
    encodings = frozenset({PROTOBUF})
    settings: IgnSettings

    def __init__(self, settings: IgnSettings) -> None:
        super().__init__(settings)
        fortress = settings.package == "ignition"  # Fortress reads IGN_*: no warning for them
        self.node = IgnNode(settings.partition, settings.ip, read_environment(fortress=fortress))
        self._delivers: dict[str, list[Deliver]] = {}

    @classmethod
    def carries(cls, message_type: MessageType) -> bool:
        name = message_type.name
        return super().carries(message_type) and (name.isidentifier() or name.startswith(_PACKAGE_PREFIXES))

    @classmethod
    def check_source(cls, name: str) -> None:
        if not _TOPIC.fullmatch(name):  # ign-transport subscribes by exact topic: a pattern never appears
            raise InvalidName(f"an ign source is one topic name, not a pattern: {name!r}")

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

        self.node.subscribe(pattern, self.wire_type_name(message_type), on_message)

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        node, typename = self.node, self.wire_type_name(message_type)
        node.advertise(name, typename)  # seen by `gz topic -l` from the first message on
        return CallPublisher(lambda data: node.publish(name, data, typename))

    def wire_type_name(self, message_type: MessageType) -> str:
        return wire_type_name(message_type.name, self.settings.package)

    def start(self) -> None:
        self.node.start()

    def describe(self) -> str:
        return f"ign-transport partition {self.node.partition} on {self.node.address}, {self.settings.package}.msgs names"

    def errors(self) -> Mapping[str, int]:
        return self.node.errors

    def close(self) -> None:
        self.node.close()
