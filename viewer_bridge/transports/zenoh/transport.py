"""Zenoh as a transport: ROS 2 in rmw_zenoh's wire format, and raw LCM channels across networks.

One Zenoh session carries two kinds of route:
- CDR types are ROS 2 topics as rmw_zenoh (Jazzy) writes them: a node `node` in `namespace` on
  domain `ROS_DOMAIN_ID`, its publishers and subscribers announced by liveliness tokens, so
  `ros2 topic list` under rmw_zenoh shows them. Names resolve as ROS resolves them (relative
  under the namespace, `~` under the node). A source that is a regular expression is matched
  against the topics the graph's publishers announce, once a second; a source of type `*` takes
  each topic whose type is a generated LCM type the router knows (`transports.topic_types`, as
  the ROS 2 transport does), and one of type `**` any topic, subscribed with the hash its publisher
  announces, but for those this node publishes on. Every message carries its topic's type
  (`Received.message_type`).
- LCM types are raw LCM messages under `<lcm_prefix>/<channel>`: a source regex is matched
  against the channel, so two bridges join two LCM buses through a router.
The session is `viewer_bridge.transports.zenoh.session`'s; eclipse-zenoh is imported when the
transport is made, not when a config naming it is checked.
"""

from __future__ import annotations

import dataclasses
import os
import re
import threading
from collections import Counter
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field, ValidationInfo, field_validator

from viewer_bridge.errors import InvalidName, InvalidSetting, TransportUnavailable
from viewer_bridge.shared import Shared
from viewer_bridge.transports.base import (
    CDR,
    DURABILITY,
    LCM,
    Deliver,
    Exposure,
    MessageType,
    Publisher,
    Qos,
    Received,
    Transport,
    TransportSettings,
)
from viewer_bridge.transports.ros_names import namespace_problem, node_name_problem
from viewer_bridge.transports.ros_qos import Offered, followed
from viewer_bridge.transports.topic_types import EVERY, TopicTypes, found_in_graph
from viewer_bridge.transports.zenoh import keys
from viewer_bridge.util.extras import missing

if TYPE_CHECKING:
    import zenoh

    from viewer_bridge.transports.zenoh.entities import Graph, LastValues, LcmPublisher, RosPublisher
    from viewer_bridge.transports.zenoh.session import Link

_PLAIN_TOPIC = re.compile(r"[A-Za-z0-9_/~{}]+")  # one topic, not a pattern (fullmatch: `$` takes "name\n")
_NOT_IN_KEYS = re.compile(r"[*$?#]")  # Zenoh's wildcards and reserved characters


def _topic_type(message_type: MessageType) -> keys.TopicType:
    """A CDR type's rmw_zenoh names and hash: from the definition it carries, else rosbags'."""
    definition = message_type.definition
    if definition is None:
        return keys.topic_type(message_type.name)
    return keys.TopicType(message_type.name, keys.dds_type_name(message_type.name), definition.rihs01)


class ZenohSettings(TransportSettings):
    mode: Literal["client", "peer", "router"] | None = None  # None: client, or the config file's
    connect: list[str] | None = None  # None: tcp/localhost:7447 (rmw_zenohd; a router: none), or the file's
    listen: list[str] | None = None  # None: no listening port (a router: tcp/127.0.0.1:7447), or the file's
    config_file: str | None = None  # a Zenoh JSON5 config; None: ZENOH_SESSION_CONFIG_URI, if set
    config: dict[
        str, Any
    ] = {}  # Zenoh config keys, set last: {"transport/link/tls/root_ca_certificate": PATH}
    domain_id: int | None = Field(None, ge=0, le=232)  # None: ROS_DOMAIN_ID, else 0
    node: str = "viewer_bridge"
    namespace: str = ""
    enclave: str = "/"
    lcm_prefix: str = "lcm"  # LCM channels travel under <lcm_prefix>/<channel>

    @field_validator("node", "namespace")
    @classmethod
    def _valid_ros_name(cls, name: str, info: ValidationInfo) -> str:
        problem = node_name_problem(name) if info.field_name == "node" else namespace_problem(name)
        if problem is not None:
            raise InvalidName(f"{name!r} is not a valid ROS 2 {info.field_name}: {problem}")
        return name

    @field_validator("connect", "listen")
    @classmethod
    def _valid_endpoints(cls, endpoints: list[str] | None) -> list[str] | None:
        for endpoint in endpoints or ():
            if problem := endpoint_problem(endpoint):
                raise InvalidSetting(f"{endpoint!r} is not a Zenoh endpoint: {problem}")
        return endpoints

    @field_validator("lcm_prefix")
    @classmethod
    def _valid_prefix(cls, prefix: str) -> str:
        if problem := key_problem(prefix):
            raise InvalidName(f"{prefix!r} cannot start a Zenoh key: {problem}")
        return prefix


# Zenoh's links for these protocols resolve their address as Rust's `ToSocketAddrs` does: `host:port`,
# the port a 16-bit number (an IPv6 host in brackets). Zenoh checks that only when it connects, and
# then retries forever; the other protocols (unixsock-stream, serial, ...) take other addresses.
_SOCKET_PROTOCOLS = frozenset({"tcp", "udp", "tls", "quic", "ws"})


def endpoint_problem(endpoint: str) -> str | None:
    """What keeps `endpoint` from being one Zenoh can open: the form Zenoh parses
    (`<protocol>/<address>[?<metadata>][#<config>]`), and a socket address's `host:port`."""
    locator = endpoint.partition("#")[0].partition("?")[0]
    protocol, slash, address = locator.partition("/")
    if not (protocol and slash and address):
        return "expected <protocol>/<address>, e.g. tcp/localhost:7447"
    if protocol not in _SOCKET_PROTOCOLS:
        return None
    host, colon, port = address.rpartition(":")
    if not (host and colon):
        return f"a {protocol} address is host:port, e.g. {protocol}/localhost:7447"
    if not (port.isdigit() and int(port) <= 65535):
        return f"the port {port!r} is not a number from 0 to 65535"
    return None


def key_problem(name: str) -> str | None:
    """What keeps `name` (a topic, its leading `/` dropped, or a channel) from being a Zenoh key."""
    key = name.removeprefix("/")
    if not key:
        return "it is empty"
    if found := _NOT_IN_KEYS.search(key):
        return f"{found.group()!r} is a Zenoh wildcard or reserved character"
    if "" in key.split("/"):
        return "it has an empty part (// or a trailing /)"
    return None


def following(asked: Qos, publishers: list[Offered]) -> Qos:
    """The QoS a Zenoh subscription takes from its topic's publishers' tokens: the ROS 2 table
    (`viewer_bridge.transports.ros_qos`), but that one which follows durability always asks the
    publishers' caches. Zenoh matches every subscriber to every publisher, so there is nothing to
    fall out with: rmw_zenoh's transient-local publishers answer with their history, the others
    with nothing, and their live samples arrive either way."""
    qos = followed(asked, publishers)
    return dataclasses.replace(qos, latched=True) if DURABILITY in asked.follow else qos


class ZenohTransport(Transport):
    """One Zenoh session; ROS 2 entities of one node, and LCM channels under a prefix."""

    Settings = ZenohSettings
    encodings = frozenset({CDR, LCM})
    ros_graph = True  # rmw_zenoh's
    plain_publishers = True
    settings: ZenohSettings

    @classmethod
    def check_source(cls, name: str) -> None:
        if _PLAIN_TOPIC.fullmatch(name) and (problem := key_problem(name)):
            raise InvalidName(f"{name!r} cannot be a Zenoh key: {problem}")

    @classmethod
    def check_destination(cls, name: str) -> None:
        if problem := key_problem(name):
            raise InvalidName(f"{name!r} cannot be a Zenoh key: {problem}")

    def __init__(self, settings: ZenohSettings, shared: Shared | None = None) -> None:
        super().__init__(settings)
        try:
            from viewer_bridge.transports.zenoh import entities, session
        except ImportError as error:
            raise missing(error, "the zenoh transport") from None
        wanted = {"mode": settings.mode, "connect": settings.connect, "listen": settings.listen}
        file, pairs = session.session_config(settings.config_file, wanted, settings.config, os.environ)
        # a bad file or key: refused now, not at every attempt
        mode, connect, listen = session.described(session.make_config(file, pairs))
        # for the start line: where it listens (a router, a peer others connect to) and what it dials
        where = [f"listening on {', '.join(listen)}"] if listen else []
        if connect or not listen:
            where.append(f"connecting to {', '.join(connect) or 'no endpoint'}")
        self._where = ", ".join([mode, *where])
        self.link: Link = session.Link(
            lambda: session.make_config(file, pairs), self._where, client=mode == "client"
        )
        self.domain = (
            settings.domain_id
            if settings.domain_id is not None
            else int(os.environ.get("ROS_DOMAIN_ID") or 0)
        )
        namespace = "/" + settings.namespace.strip("/")
        self.node = keys.NodeName(settings.node, namespace, settings.enclave)
        self._errors: Counter[str] = Counter()
        self.graph: Graph = entities.Graph(self._errors)
        self._publishers: list[RosPublisher | LcmPublisher] = []
        self._topics: dict[str, list[Deliver]] = {}  # topic -> every route reading it
        self._published: set[str] = set()  # the topics this node publishes on
        self._patterns: list[tuple[re.Pattern[str], MessageType, Qos, Deliver]] = []
        self._types = TopicTypes(Shared() if shared is None else shared)  # what a `*` pattern takes
        self._channels: list[tuple[re.Pattern[str], Deliver]] = []
        self._channels_latched = False  # a route asked for each channel's last message on joining
        self._last_values: LastValues | None = None  # made with the first latched LCM publisher
        self._next_id = 1  # the node is entity 0; its publishers and subscribers follow
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._discovery = threading.Thread(target=self._discover, name="zenoh discovery", daemon=True)

    @classmethod
    def create(cls, settings: TransportSettings, shared: Shared) -> ZenohTransport:
        assert isinstance(settings, ZenohSettings)
        return cls(settings, shared)

    # --- names -------------------------------------------------------------------------------------

    def resolve(self, name: str) -> str:
        """A topic name as ROS resolves it: absolute as is, `~` under the node, else under the namespace."""
        namespace = self.node.namespace.rstrip("/")
        if name.startswith("/"):
            return name
        if name.startswith("~"):
            return f"{namespace}/{self.node.name}{name[1:]}"
        return f"{namespace}/{name}"

    def _entity_id(self) -> int:
        with self._lock:
            self._next_id += 1
            return self._next_id - 1

    def _token(
        self, kind: str, topic: str, topic_type: keys.TopicType, qos: Qos
    ) -> Callable[[str], keys.Token]:
        """The token of one publisher or subscriber, once the session's id is known."""
        entity_id = self._entity_id()
        token_qos = keys.TokenQos(qos.reliable, qos.latched, False, qos.depth)
        entity = keys.TopicEntity(topic, topic_type.dds_name, topic_type.hash, token_qos)

        def token(zid: str) -> keys.Token:
            return keys.Token(self.domain, zid, 0, entity_id, kind, self.node, entity)

        return token

    def require(self, message_types: Iterable[MessageType]) -> None:
        for message_type in message_types:
            if (
                message_type.encoding == CDR
                and message_type.definition is None
                and not found_in_graph(message_type)
            ):
                try:
                    keys.topic_type(message_type.name)
                except (KeyError, ValueError):
                    raise TransportUnavailable(
                        f"the zenoh transport has no definition of {message_type.name} (its RIHS01 hash comes "
                        "from rosbags' Jazzy types)"
                    ) from None

    # --- publishing ----------------------------------------------------------------------------------

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        from viewer_bridge.transports.zenoh.entities import LastValues, LcmPublisher, RosPublisher

        publisher: RosPublisher | LcmPublisher
        if message_type.encoding == LCM:
            with self._lock:
                if qos.latched and self._last_values is None:
                    self._last_values = LastValues(self.link, self.settings.lcm_prefix)
            publisher = LcmPublisher(
                self.link, self._lcm_key(name), qos, self._last_values if qos.latched else None
            )
        else:
            topic, topic_type = self.resolve(name), _topic_type(message_type)
            self._published.add(topic)
            token = self._token(keys.PUBLISHER, topic, topic_type, qos)
            publisher = RosPublisher(
                self.link, self.graph, keys.data_key(self.domain, topic, topic_type), token, qos
            )
        self._publishers.append(publisher)
        return publisher

    def _lcm_key(self, channel: str) -> str:
        if problem := key_problem(channel):
            raise InvalidName(f"LCM channel {channel!r} cannot be a Zenoh key: {problem}")
        return f"{self.settings.lcm_prefix}/{channel}"

    # --- subscribing ---------------------------------------------------------------------------------

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        """LCM: channels under the prefix that fully match `pattern`. CDR: a topic, or a regex matched
        against the topics the graph's publishers announce."""
        if message_type.encoding == LCM:
            self._channels.append((re.compile(pattern), deliver))
            self._channels_latched = self._channels_latched or qos.latched
        elif _PLAIN_TOPIC.fullmatch(pattern) and not found_in_graph(message_type):
            self._subscribe_topic(pattern, message_type, qos, deliver)
        else:
            self._patterns.append((re.compile(pattern), message_type, qos, deliver))

    def _subscribe_topic(
        self, topic: str, message_type: MessageType, qos: Qos, deliver: Deliver, type_hash: str | None = None
    ) -> None:
        """Subscribe `topic`; `type_hash`: the one its publisher announced (a type of any package,
        which rosbags' store may not know), else the type's own."""
        from viewer_bridge.transports.zenoh import entities

        with self._lock:
            delivers = self._topics.get(topic)
            if delivers is not None:  # another route reads it already: share the subscription
                if deliver not in delivers:
                    delivers.append(deliver)
                return
            delivers = self._topics[topic] = [deliver]
        resolved = self.resolve(topic)
        qos = following(qos, self.graph.offered(resolved))
        topic_type = (
            _topic_type(message_type)
            if type_hash is None
            else keys.TopicType(message_type.name, keys.dds_type_name(message_type.name), type_hash)
        )
        key = keys.data_key(self.domain, resolved, topic_type)
        token = self._token(keys.SUBSCRIBER, resolved, topic_type, qos)
        on_sample = self.link.calling(entities.ros_receiver(topic, message_type, delivers, self._errors))

        def declare(session: zenoh.Session) -> None:
            self.link.hold(entities.declare_subscriber(session, key, qos, on_sample))
            self.link.hold(session.liveliness().declare_token(token(str(session.zid())).key()))

        self.link.when_open(declare)

    def _discover(self) -> None:
        """Once a second: topics the graph's publishers announce that a source regex matches."""
        while not self._stop.wait(1.0):
            own = self.graph.published_by(self.node) | self._published
            for topic, dds_type, type_hash in self.graph.publishers():
                announced = [name] if (name := keys.ros_type_name(dds_type)) else []
                for pattern, wanted, qos, deliver in self._patterns:
                    if not pattern.fullmatch(topic) or (wanted.name == EVERY and topic in own):
                        continue
                    if qos.admits is not None and not qos.admits(topic):
                        continue  # a topic no route would carry (a command channel not allowed) costs nothing
                    if found := self._types.pick(wanted, topic, announced):
                        self._subscribe_topic(
                            topic, found, qos, deliver, type_hash if wanted.name == EVERY else None
                        )

    def _on_lcm(self, sample: zenoh.Sample) -> None:
        channel = str(sample.key_expr)[len(self.settings.lcm_prefix) + 1 :]
        if not channel or keys.wildcard(channel):  # a wildcard put would write every channel it covers
            self._errors["bad_key"] += 1
            return
        message = None
        for pattern, deliver in self._channels:
            if pattern.fullmatch(channel):
                message = message or Received(channel, sample.payload.to_bytes())
                deliver(message)

    # --- running -------------------------------------------------------------------------------------

    def start(self) -> None:
        from viewer_bridge.transports.zenoh import entities

        node_token = keys.Token(self.domain, "", 0, 0, keys.NODE, self.node)
        graph_key = f"{keys.ADMIN_SPACE}/{self.domain}/**"
        prefix = self.settings.lcm_prefix
        latched = self._channels_latched
        on_graph, on_lcm = self.link.calling(self.graph.on_sample), self.link.calling(self._on_lcm)

        def declare(session: zenoh.Session) -> None:
            token = dataclasses.replace(node_token, zid=str(session.zid()))
            self.link.hold(session.liveliness().declare_token(token.key()))
            self.link.hold(session.liveliness().declare_subscriber(graph_key, on_graph, history=True))
            if self._channels:
                self.link.hold(session.declare_subscriber(f"{prefix}/**", on_lcm))
                if latched:  # what was sent before this bridge joined: each channel's last message
                    entities.ask_last_values(session, prefix, on_lcm)

        self.link.when_open(declare)
        self.link.start()
        if self._patterns:
            self._discovery.start()

    def describe(self) -> str:
        node = f"{self.node.namespace.rstrip('/')}/{self.node.name}"
        return f"Zenoh {self._where}: ROS domain {self.domain}, node {node}; LCM under {self.settings.lcm_prefix}/"

    def exposure(self) -> Exposure:
        return Exposure(f"Zenoh ({self._where})", (
            "commands are taken from every Zenoh session that reaches this one (through its router too): "
            "limit who may publish on the command topics with the Zenoh router's access control "
            "(the Zenoh guide, docs/zenoh.md: who may command your robot)"
        ))  # fmt: skip

    def errors(self) -> dict[str, int]:
        counts = dict(self._errors)
        unsent = sum(publisher.unsent for publisher in self._publishers)
        if unsent:
            counts["unsent_no_router"] = unsent
        return counts

    def close(self) -> None:
        self._stop.set()
        if self._discovery.is_alive():
            self._discovery.join(timeout=2)
        self.link.close()
