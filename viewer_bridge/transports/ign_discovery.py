"""ign/gz-transport discovery without sockets: what a node reads in a datagram and what it answers.

docs/PROTOCOLS.md sections 4 and 10. A datagram is `[uint16 length, little-endian][Discovery]`,
sent to the discovery group (239.255.0.7:10317; a heartbeat to 10318 as well) and to every
unicast relay (`GZ_RELAY`, with the RELAY flag), wire version 10, or 110 when topic statistics
are on; the bridge reads both versions. `Discovery` is one node's side of it: every second a
HEARTBEAT and an ADVERTISE per topic it publishes; SUBSCRIBE answered with ADVERTISE;
SUBSCRIBERS_REQ (gz-transport 13's `gz topic -l`) with a SUBSCRIBERS_REP per subscription. When a
publisher it wants advertises, the address is checked, the node connects, and NEW_CONNECTION
announces it (a C++ publisher sends nothing to a subscriber that has not). A peer silent for
3 s is forgotten. A subscription accepts its message in either package's spelling.

It owns no socket: datagrams go out through `send(data, (host, port))` and connections through
`connect(address)`, which the node (viewer_bridge/transports/ign.py) implements and a fuzz target or a
test records. Nothing in a datagram raises here: what cannot be used is passed to
`report(kind, text)` and skipped.
"""

from __future__ import annotations

import re
import struct
import threading
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from google.protobuf.message import DecodeError as ProtobufDecodeError

from viewer_bridge.formats.ign.schema import MESSAGES, spellings
from viewer_bridge.transports.ign_environment import NodeEnvironment

WIRE_VERSION = 10
STATISTICS_VERSION = 110  # WIRE_VERSION + 100: topic statistics on, a fifth data frame
HEARTBEAT_S = 1.0
SILENCE_S = 3.0
ANY_TYPE = "google.protobuf.Message"

Record = MESSAGES.Discovery  # a discovery message; its types are Record.ADVERTISE ... SUBSCRIBERS_REP
Callback = Callable[[str, bytes, int], None]  # topic, serialized protobuf, receive time in microseconds
Send = Callable[[bytes, tuple[str, int]], None]
Report = Callable[[str, str], None]  # error kind, text


@dataclass
class Remote:
    """A publisher this node subscribes to, as its ADVERTISE described it."""

    topic: str
    address: str
    process_uuid: str
    node_uuid: str
    msg_type: str


@dataclass
class Subscription:
    topic: str  # full name, @/partition@/topic
    msg_type: str  # as this node names it (its SUBSCRIBERS_REP)
    accepts: frozenset[str] | None  # the type names it takes; None: any
    callbacks: list[Callback] = field(default_factory=list)


def subscription(topic: str, msg_type: str) -> Subscription:
    return Subscription(topic, msg_type, None if msg_type == ANY_TYPE else spellings(msg_type))


class Discovery:
    """One node's discovery: what it advertises and wants, and its answers; thread-safe."""

    def __init__(
        self, environment: NodeEnvironment, address: str, send: Send, connect: Callable[[str], None],
        report: Report,
    ) -> None:  # fmt: skip
        self.environment = environment
        self.address = address  # where this node's data is published
        self.version = STATISTICS_VERSION if environment.topic_statistics else WIRE_VERSION
        self.process_uuid = str(uuid.uuid4())
        self.node_uuid = str(uuid.uuid4())
        self.advertised: dict[str, str] = {}  # full topic -> type
        self.subscriptions: dict[str, Subscription] = {}
        self.remotes: dict[tuple[str, str], Remote] = {}  # (process uuid, topic) -> publisher
        self.relays = environment.relays  # a tuple, replaced when one is added: other threads send
        self._send_datagram, self._connect, self._report = send, connect, report
        self._connected: set[str] = set()  # addresses connected to
        self._last_seen: dict[str, float] = {}
        self._lock = threading.Lock()  # advertise and subscribe come from any thread
        self._handlers: dict[int, Callable[[Any, str], None]] = {
            Record.ADVERTISE: self._on_advertise, Record.SUBSCRIBE: self._on_subscribe,
            Record.UNADVERTISE: self._on_unadvertise, Record.BYE: self._on_bye,
            Record.SUBSCRIBERS_REQ: self._on_subscribers_request,
            Record.HEARTBEAT: _nothing, Record.NEW_CONNECTION: _nothing, Record.END_CONNECTION: _nothing,
            Record.SUBSCRIBERS_REP: _nothing,  # other nodes' subscribers: the bridge lists none
        }  # fmt: skip

    # --- what this node says ---------------------------------------------------------------------------

    def advertise(self, full: str, msg_type: str) -> None:
        with self._lock:
            self.advertised[full] = msg_type
        self.send(self._publisher_record(Record.ADVERTISE, full, msg_type))

    def subscribe(self, full: str, msg_type: str) -> Subscription:
        """The subscription of `full` (the first caller's type decides), asked for at once."""
        with self._lock:
            wanted = self.subscriptions.setdefault(full, subscription(full, msg_type))
        self._send_subscribe(full)
        return wanted

    def beat(self, now: float) -> None:
        """Every HEARTBEAT_S: HEARTBEAT, ADVERTISE again, SUBSCRIBE until answered, forget the silent."""
        self.send(self.header(Record.HEARTBEAT))
        self.send(self.header(Record.HEARTBEAT), self.environment.service_port)
        for full, msg_type in list(self.advertised.items()):
            self.send(self._publisher_record(Record.ADVERTISE, full, msg_type))
        for full in list(self.subscriptions):
            if not any(key[1] == full for key in self.remotes):
                self._send_subscribe(full)
        for process_uuid, seen in list(self._last_seen.items()):
            if now - seen > SILENCE_S:
                self._forget(process_uuid)

    def goodbye(self) -> None:
        """UNADVERTISE every topic, END_CONNECTION to every publisher, BYE."""
        for full, msg_type in list(self.advertised.items()):
            self.send(self._publisher_record(Record.UNADVERTISE, full, msg_type))
        for remote in list(self.remotes.values()):
            self.send(self._connection_record(Record.END_CONNECTION, remote))
        self.send(self.header(Record.BYE))

    def header(self, kind: int) -> Any:
        return Record(version=self.version, process_uuid=self.process_uuid, type=kind)

    def send(self, message: Any, port: int | None = None) -> None:
        """To the group, and to every relay with the RELAY flag set (as gz-transport sends)."""
        port = self.environment.message_port if port is None else port
        self._send_datagram(datagram(message), (self.environment.group, port))
        if self.relays:
            message.flags.relay = True
            data = datagram(message)
            for relay in self.relays:
                self._send_datagram(data, (relay, port))

    def _publisher_record(self, kind: int, full: str, msg_type: str) -> Any:
        """ADVERTISE, UNADVERTISE, SUBSCRIBERS_REP: this node's publisher (or subscriber) of `full`."""
        message = self.header(kind)
        publisher = message.pub
        publisher.topic, publisher.address = full, self.address
        publisher.process_uuid, publisher.node_uuid = self.process_uuid, self.node_uuid
        publisher.scope = Record.Publisher.ALL
        publisher.msg_pub.ctrl = ""
        publisher.msg_pub.msg_type = msg_type
        return message

    def _connection_record(self, kind: int, remote: Remote) -> Any:
        """NEW_CONNECTION / END_CONNECTION: the publisher's record, with our uuids."""
        message = self.header(kind)
        publisher = message.pub
        publisher.topic, publisher.address = remote.topic, remote.address
        publisher.process_uuid, publisher.node_uuid = self.process_uuid, self.node_uuid
        publisher.scope = Record.Publisher.ALL
        publisher.msg_pub.ctrl = remote.process_uuid
        publisher.msg_pub.msg_type = remote.msg_type
        return message

    def _send_subscribe(self, full: str) -> None:
        message = self.header(Record.SUBSCRIBE)
        message.sub.topic = full
        self.send(message)

    # --- what it reads -----------------------------------------------------------------------------------

    def on_datagram(self, data: bytes, sender: str, now: float) -> None:
        """One datagram from `sender` (an IPv4 address) at monotonic time `now`."""
        if len(data) < 2 or struct.unpack_from("<H", data)[0] + 2 != len(data):
            self._report("discovery_length", f"datagram of {len(data)} bytes: its length prefix disagrees")
            return
        message = Record()
        try:
            message.ParseFromString(data[2:])
        except ProtobufDecodeError as error:
            self._report("discovery_parse", f"discovery datagram does not parse: {error}")
            return
        if message.version not in (WIRE_VERSION, STATISTICS_VERSION):
            versions = f"{WIRE_VERSION} or {STATISTICS_VERSION}"
            self._report("discovery_version", f"discovery wire version {message.version}, not {versions}")
            return
        if message.process_uuid == self.process_uuid:
            return  # our own, looped back
        if message.flags.relay:  # from a relay: to this host's group (where it is read), not to relays
            message.flags.relay, message.flags.no_relay = False, True
            self._send_datagram(datagram(message), (self.environment.group, self.environment.message_port))
            if sender not in self.relays:
                self.relays = (*self.relays, sender)
            return
        if self.relays and not message.flags.no_relay:  # from the group: on to the relays
            message.flags.relay = True
            data = datagram(message)
            for relay in self.relays:
                self._send_datagram(data, (relay, self.environment.message_port))
        self._last_seen[message.process_uuid] = now
        handler = self._handlers.get(message.type)
        if handler is None:
            self._report(
                "discovery_type", f"discovery message type {message.type}, which the bridge does not know"
            )
            return
        handler(message, sender)

    def _on_advertise(self, message: Any, sender: str) -> None:
        publisher = message.pub
        with self._lock:
            wanted = self.subscriptions.get(publisher.topic)
        if wanted is None or not publisher.address:
            return
        msg_type = publisher.msg_pub.msg_type
        if wanted.accepts is not None and msg_type not in wanted.accepts:
            self._report("type_mismatch", f"{publisher.topic} is {msg_type[:80]}, not {wanted.msg_type}")
            return
        key = (message.process_uuid, publisher.topic)
        if key in self.remotes:
            return
        if not is_tcp_address(publisher.address):  # ZMQ would raise, and end the node's thread
            self._report(
                "advertise_address", f"{publisher.topic}: not a tcp://host:port: {publisher.address[:80]!r}"
            )
            return
        remote = Remote(
            publisher.topic, publisher.address, publisher.process_uuid, publisher.node_uuid, msg_type
        )
        if remote.address not in self._connected:
            try:
                self._connect(remote.address)
            except OSError as error:  # whatever else the node refuses: counted, the node goes on
                self._report("advertise_address", f"{publisher.topic}: {remote.address[:80]!r}: {error}")
                return
            self._connected.add(remote.address)
        self.remotes[key] = remote
        self.send(self._connection_record(Record.NEW_CONNECTION, remote))

    def _on_subscribe(self, message: Any, sender: str) -> None:
        topic = message.sub.topic
        msg_type = self.advertised.get(topic)
        if msg_type is not None:
            self.send(self._publisher_record(Record.ADVERTISE, topic, msg_type))

    def _on_subscribers_request(self, message: Any, sender: str) -> None:
        """A SUBSCRIBERS_REP per subscription: gz-transport 13 lists subscribers from them."""
        with self._lock:
            wanted = [(full, each.msg_type) for full, each in self.subscriptions.items()]
        for full, msg_type in wanted:
            self.send(self._publisher_record(Record.SUBSCRIBERS_REP, full, msg_type))

    def _on_unadvertise(self, message: Any, sender: str) -> None:
        self._forget(message.process_uuid, message.pub.topic)

    def _on_bye(self, message: Any, sender: str) -> None:
        self._forget(message.process_uuid)

    def _forget(self, process_uuid: str, topic: str | None = None) -> None:
        for key in [key for key in self.remotes if key[0] == process_uuid and topic in (None, key[1])]:
            self.remotes.pop(key)
            # The node stays connected to the address: disconnecting while a peer's pipe is
            # closing trips an assertion in libzmq, and a dead endpoint costs nothing.
        if topic is None:
            self._last_seen.pop(process_uuid, None)


def _nothing(message: Any, sender: str) -> None:
    """A message type the bridge knows and has nothing to do for (the sender's time is noted)."""


def datagram(message: Any) -> bytes:
    body: bytes = message.SerializeToString()
    return struct.pack("<H", len(body)) + body


_TCP_ADDRESS = re.compile(r"tcp://(?:\[[0-9A-Fa-f:.]+\]|[^\s/:\[\]]+):([0-9]{1,5})")


def is_tcp_address(address: str) -> bool:
    """What an ign-transport publisher advertises: `tcp://host:port` (IPv6 hosts in brackets)."""
    match = _TCP_ADDRESS.fullmatch(address)
    return match is not None and 0 < int(match.group(1)) < 65536
