"""Foxglove's live WebSocket protocol as a transport, through the official foxglove-sdk.

Each name a route publishes on is a Foxglove channel (protobuf, with the schema of
its `foxglove.*` type; or CDR with the `ros2msg` schema a type's definition carries, as any LCM
type's mapping does: viewer_bridge/translators/lcm_generic.py), served to browsers on
`host:port` (127.0.0.1:8765 unless configured). A Foxglove client that subscribes is counted
(so lazy routes wake up), and a latched output's last message is logged again when a client
subscribes, so a client that connects after the load still gets the scene (SceneUpdates are
idempotent). Everything about the protocol is the SDK's; a front of ours
(viewer_bridge/transports/foxglove_front.py) always holds the public port: it refuses browser
pages of foreign origins (`allowed_origins`) and clients past `max_clients`, and, unless
`accept_websocket_v1` is false, serves clients asking for the protocol's older name,
`foxglove.websocket.v1`, as well as those asking for `foxglove.sdk.v1`, the only name the SDK's
server accepts.

As a route's source it reads what clients publish (the app's Publish and Teleop panels): unless
`client_publish` is false, the server lists the `clientPublish` capability with the encodings
`cdr` and `json`, and a route whose source pattern fully matches a client channel's topic gets
each of its messages with the message's own type (its schema name as `pkg/msg/Name`, and its
encoding) and the client it came from; the client alone hears, as an error status, what the
bridge did not take (viewer_bridge/transports/foxglove_clients.py). This goes through the front,
which reads along what clients send.

Where a config also writes an MCAP file of Foxglove messages (viewer_bridge/transports/mcap.py), the
server and the file log to one `FoxgloveContext`, as in the SDK: a message logged on a channel,
by a route to either, is written once to each, and a topic is one channel. Route a topic to one
of them (to both, each message would be written twice: the bridge warns). A latched output's
message logged again for a late client then reaches the file again too (a SceneUpdate is
idempotent: the file plays back the same).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterable, Mapping
from typing import Any
from urllib.parse import urlencode

from pydantic import Field, field_validator

from viewer_bridge.errors import BridgeError, InvalidSetting, TransportUnavailable
from viewer_bridge.formats.foxglove.schema import schema
from viewer_bridge.shared import Clock, Shared
from viewer_bridge.transports.base import (
    CDR,
    PROTOBUF,
    Deliver,
    Exposure,
    MessageType,
    Publisher,
    Qos,
    Received,
    Transport,
    TransportSettings,
)
from viewer_bridge.transports.command_policy import CommandPolicy
from viewer_bridge.transports.foxglove_clients import CLIENT_ENCODINGS, MAX_CLIENT_CHANNELS, ClientPublishing
from viewer_bridge.transports.foxglove_front import MAX_CLIENT_MESSAGE, MAX_CLIENTS, SubprotocolFront
from viewer_bridge.transports.origins import FOXGLOVE_APPS, Origins, is_origin_pattern
from viewer_bridge.transports.playback import Timeline, Timelines
from viewer_bridge.transports.sdk_tls import SdkCertificate
from viewer_bridge.util.extras import missing

try:
    import foxglove
    from foxglove.websocket import (
        Capability,
        ChannelView,
        Client,
        PlaybackControlRequest,
        PlaybackState,
        ServerListener,
    )

    from viewer_bridge.transports.foxglove_playback import FoxglovePlayback
except ImportError as error:
    raise missing(error, "the foxglove transport") from None


def carried(message_type: MessageType) -> bool:
    """Whether a Foxglove channel (live or in a file) can hold this type: Foxglove's own protobuf
    messages, or CDR of a ROS 2 type that carries its definition (an LCM type's mapping); and,
    from clients that publish, any type of the encodings they may use (`*`: each message says its own)."""
    if message_type.name == "*":
        return message_type.encoding in CLIENT_ENCODINGS
    if message_type.encoding == PROTOBUF:
        return message_type.name.startswith("foxglove.")
    return message_type.encoding == CDR and message_type.definition is not None


def require_schemas(message_types: Iterable[MessageType]) -> None:
    """Raise `TransportUnavailable` for a `foxglove.*` type whose protobuf schema is not installed."""
    for message_type in message_types:
        if message_type.definition is not None:  # its schema comes with it
            continue
        try:
            schema(message_type.name)
        except (ImportError, KeyError) as error:
            raise TransportUnavailable(
                f"foxglove-schemas-protobuf has no {message_type.name} ({error})"
            ) from None


class FoxgloveContext:
    """A router's one Foxglove context: its sinks (the live server, an MCAP file) and channels.

    The SDK makes one channel per topic and schema in a context (asked again, it returns the same
    one) and writes each message logged on it to every sink. `channel` says so when two
    transports ask for one topic: each message of it would reach every sink twice.
    """

    def __init__(self) -> None:
        self.context = foxglove.Context()
        self._asked_by: dict[str, str] = {}  # topic -> the transport that first asked for it
        self._lock = threading.Lock()

    def topics(self) -> list[str]:
        """The topics a transport has asked a channel for and not given up."""
        with self._lock:
            return sorted(self._asked_by)

    def forget(self, topic: str) -> None:
        """`topic` has no channel any more (its stream went quiet): the next to ask is the first."""
        with self._lock:
            self._asked_by.pop(topic, None)

    def channel(self, topic: str, message_type: MessageType, transport: str) -> foxglove.Channel:
        """The channel of a `foxglove.*` protobuf type on `topic`, or of a CDR type with the
        `ros2msg` schema its definition carries, for the `transport` named."""
        with self._lock:
            first = self._asked_by.setdefault(topic, transport)
        if first != transport:
            log.warning(
                "%s is routed to both the %s and the %s transport, which log to one Foxglove context: "
                "each of its messages reaches the server and the file twice (route it to one of them)",
                topic,
                first,
                transport,
            )
        if message_type.definition is not None:
            text = message_type.definition.ros2msg.encode()
            return foxglove.Channel(
                topic,
                schema=foxglove.Schema(name=message_type.name, encoding="ros2msg", data=text),
                message_encoding=CDR,
                context=self.context,
            )
        return foxglove.Channel(
            topic,
            schema=foxglove.Schema(
                name=message_type.name, encoding="protobuf", data=schema(message_type.name)
            ),
            message_encoding="protobuf",
            context=self.context,
        )


class _WithoutSdkAddress(logging.Filter):
    """Drops the SDK's own "Started server on HOST:PORT": behind the front that is an internal
    port no client should use, and the bridge's start-up line names the one to use."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Started server on")


logging.getLogger("foxglove.websocket.server").addFilter(_WithoutSdkAddress())  # the SDK's Rust log
log = logging.getLogger("viewer_bridge")


class FoxgloveSettings(TransportSettings):
    host: str = "127.0.0.1"  # this machine only, unless you mean to serve other hosts
    port: int = Field(8765, ge=0, le=65535)  # 0: any free port (the start-up line says which)
    name: str = "viewer-bridge"
    # Also serve clients that ask for the protocol's older name, foxglove.websocket.v1 (the relay
    # of ours that holds the port renames it). false: foxglove.sdk.v1 clients only.
    accept_websocket_v1: bool = True
    # Clients may publish (the app's Publish and Teleop panels) to the routes that read from
    # foxglove: the server lists the clientPublish capability (encodings cdr and json), and a
    # client hears, as an error status, what the bridge does not take. false: a read-only server
    # (no clientPublish capability); a route that reads from foxglove then gets nothing (said once).
    client_publish: bool = True
    # Origins of browser pages that may connect, besides loopback pages and Foxglove's app (a
    # request without an Origin header, from no browser, always may): exact ("https://lab.example:8080")
    # or with * for any run of characters but "/" ("https://*.lab.example"); ["*"]: any page.
    allowed_origins: list[str] = Field(default_factory=list)
    max_clients: int = Field(MAX_CLIENTS, ge=1)  # connected at once; one more is answered HTTP 503
    max_client_channels: int = Field(MAX_CLIENT_CHANNELS, ge=1)  # advertised by one client at once
    max_client_message_bytes: int = Field(MAX_CLIENT_MESSAGE, ge=1024)  # read from a client; longer: refused

    @field_validator("allowed_origins")
    @classmethod
    def _origins(cls, entries: list[str]) -> list[str]:
        for entry in entries:
            if not is_origin_pattern(entry):
                raise InvalidSetting(f"{entry!r} is no origin: write scheme://host[:port] (no path), with * for any "
                                     "run of characters but '/', or '*' alone for every origin")  # fmt: skip
        return entries


class _Subscribers:
    """Which clients subscribe to each Foxglove channel, by channel id.

    Kept apart from our publishers because the SDK advertises a channel the moment it is made:
    a connected client may subscribe, and the SDK call `on_subscribe`, before `publisher` has
    stored the channel it just made. Counted here, that subscription is not lost (a lazy route
    asking its publisher would otherwise hear "nobody" for as long as that client stays).
    """

    def __init__(self) -> None:
        self._clients: dict[int, set[int]] = {}  # channel id -> client ids
        self._lock = threading.Lock()  # the SDK calls on its threads, routes ask on theirs

    def add(self, channel_id: int, client: int) -> None:
        with self._lock:
            self._clients.setdefault(channel_id, set()).add(client)

    def discard(self, channel_id: int, client: int) -> None:
        with self._lock:
            clients = self._clients.get(channel_id)
            if clients is not None:
                clients.discard(client)
                if not clients:
                    del self._clients[channel_id]

    def count(self, channel_id: int) -> int:
        with self._lock:
            return len(self._clients.get(channel_id, ()))

    def drop(self, channel_id: int) -> None:
        """A channel closed: its subscribers are no more."""
        with self._lock:
            self._clients.pop(channel_id, None)


class _Channel:
    """A publisher on one Foxglove channel: its subscribers, and its last message when latched.
    Its log times are the SDK's (now) unless a played log's timeline or the sim clock gives them."""

    def __init__(
        self,
        channel: foxglove.Channel,
        latched: bool,
        subscribers: _Subscribers,
        log_time: Callable[[], int] | None = None,
        forget: Callable[[_Channel], None] = lambda channel: None,
    ) -> None:
        """`log_time`: the time (ns) to stamp each message with (a played log's timeline, the sim
        clock), else the SDK's now. `forget`: called when the channel is closed."""
        self.channel = channel
        self._forget = forget
        self.id = channel.id()
        self.latched = latched
        self.last: bytes | None = None
        self.unsent = 0  # a channel logs to every client and file of its context: nothing stays unsent
        self._subscribers = subscribers
        self._log_time = log_time

    def publish(self, data: bytes) -> None:
        if self.latched:
            self.last = data
        self._log(data)

    def _log(self, data: bytes) -> None:
        if self._log_time is None:
            self.channel.log(data)
        else:
            self.channel.log(data, log_time=self._log_time())

    def subscriber_count(self) -> int:
        return self._subscribers.count(self.id)

    def close(self) -> None:
        """Its route let its stream go: clients see the channel go, and the transport forgets it."""
        self._forget(self)
        self.channel.close()

    def subscribed(self) -> None:
        """A client subscribed: it gets the current state (others see it again)."""
        if self.last is not None:
            self._log(self.last)


class _Listener(ServerListener):
    """Clients subscribing to and unsubscribing from channels (the SDK calls it on its threads)."""

    def __init__(
        self,
        channels: dict[int, _Channel],
        subscribers: _Subscribers,
        playback: FoxglovePlayback | None,
        subscribed: Callable[[], None] = lambda: None,
    ) -> None:
        """`subscribed`: called as a client subscribes (the server tells the time again then)."""
        self._channels = channels
        self._subscribers = subscribers
        self._playback = playback
        self._subscribed = subscribed

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self._subscribed()
        self._subscribers.add(channel.id, client.id)  # counted even before `publisher` stores the channel
        found = self._channels.get(channel.id)
        if found is not None:  # not yet stored: nothing was published on it, nothing to send again
            found.subscribed()

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self._subscribers.discard(channel.id, client.id)

    def on_playback_control_request(self, request: PlaybackControlRequest) -> PlaybackState | None:
        return None if self._playback is None else self._playback.on_request(request)


class FoxgloveTransport(Transport):
    """A Foxglove WebSocket server on a context of its own, or of its router's (`create`)."""

    Settings = FoxgloveSettings
    encodings = frozenset({PROTOBUF, CDR})
    settings: FoxgloveSettings

    def __init__(
        self,
        settings: FoxgloveSettings,
        context: FoxgloveContext | None = None,
        *,
        accept_commands: bool = True,
        timeline: Timeline | None = None,
        clock: Clock | None = None,
        sdk_tls: bool = True,
    ) -> None:
        """`accept_commands`: whether what clients publish can land anywhere (a router's config
        allows some command channel); without it the server offers no publishing, and a client
        that publishes anyway is told why. `timeline`: a played log's (`viewer-bridge play`), which
        clients drive (viewer_bridge/transports/foxglove_playback.py); each message is stamped with
        its time when sent, and the timeline is Foxglove's time. `clock`: the bridge's; with
        `time: sim` (and no timeline) the server lists the `time` capability and broadcasts each
        new sim time to every client (messages' log times are that clock's too), so Foxglove's
        current time is Drake's. `sdk_tls`: the SDK's server behind the front speaks TLS only,
        with a certificate made for this run (viewer_bridge/transports/sdk_tls.py: no web page can
        read it); false only to measure what that costs (bench/foxglove_live.py)."""
        super().__init__(settings)
        self._channels: dict[int, _Channel] = {}  # by Foxglove channel id
        self._subscribers = _Subscribers()
        self.context = FoxgloveContext() if context is None else context
        self.clock = Clock() if clock is None else clock
        self.clients = ClientPublishing(settings.max_client_channels) if settings.client_publish else None
        publishing = self.clients is not None and accept_commands
        options: dict[str, Any] = {}
        if publishing:
            options = {
                "capabilities": [Capability.ClientPublish],
                "supported_encodings": list(CLIENT_ENCODINGS),
            }
        self._playback = None if timeline is None else FoxglovePlayback(timeline)
        self._sim_time = self.clock.sim and self._playback is None  # a played log's timeline is the time
        if self._playback is not None:
            options = self._playback.server_options(options)
        elif self._sim_time:
            options["capabilities"] = [*options.get("capabilities", []), Capability.Time]
        certificate = SdkCertificate.make() if sdk_tls else None
        if certificate is not None:
            options |= {"tls_cert": certificate.cert_pem, "tls_key": certificate.key_pem}
        try:
            self.server = foxglove.start_server(
                name=settings.name,
                host="127.0.0.1",  # behind the front, which holds the public port
                port=0,
                context=self.context.context,
                server_listener=_Listener(self._channels, self._subscribers, self._playback, self._tell_time),
                **options,
            )
        except Exception as error:  # the SDK raises its own error types, e.g. for a port in use
            raise self._cannot_listen(error) from None
        if self._playback is not None:
            self._playback.attach(self.server)
        # one callable: the clock's listener, and its removal
        self._broadcast_time = self.server.broadcast_time
        if self._sim_time:
            self.clock.listen(self._broadcast_time)
        try:
            self.front = SubprotocolFront(
                settings.host, settings.port, self.server.port,
                rename=settings.accept_websocket_v1, reader=self.clients,
                origins=Origins(settings.allowed_origins, trusted=FOXGLOVE_APPS),
                max_clients=settings.max_clients, max_message_bytes=settings.max_client_message_bytes,
                certificate=certificate,
            )  # fmt: skip
        except OSError as error:  # a port in use, an address not of this machine
            self.clock.unlisten(self._broadcast_time)
            self.server.stop()
            raise self._cannot_listen(error) from None

    @classmethod
    def create(cls, settings: TransportSettings, shared: Shared) -> FoxgloveTransport:
        assert isinstance(settings, FoxgloveSettings)
        # without an allowed channel nothing clients publish lands
        accept = bool(shared.given(CommandPolicy).allow)
        # an MCAP file logs to it too
        timeline = shared.given(Timelines).timeline  # `viewer-bridge play`'s
        return cls(
            settings,
            shared.get(FoxgloveContext),
            accept_commands=accept,
            timeline=timeline,
            clock=shared.clock,
        )

    def _cannot_listen(self, error: Exception) -> TransportUnavailable:
        where = f"{self.settings.host}:{self.settings.port}"
        return TransportUnavailable(f"the foxglove server cannot listen on {where} (foxglove.port): {error}")

    @property
    def port(self) -> int:
        """The port clients connect to."""
        return self.front.port

    @classmethod
    def carries(cls, message_type: MessageType) -> bool:
        return carried(message_type)

    def require(self, message_types: Iterable[MessageType]) -> None:
        require_schemas([message_type for message_type in message_types if message_type.name != "*"])

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        """Deliver what clients publish on topics that fully match `pattern`, each message with its own type."""
        if self.clients is None:  # a read-only server: the route stays idle, the rest of the config runs
            log.warning(
                "foxglove.client_publish is false: the route reading %r from Foxglove clients gets nothing",
                pattern,
            )
            return
        self.clients.subscribe(pattern, deliver)

    def rejected(self, message: Received, error: BridgeError) -> None:
        """Say to the client that published `message` why a route refused it (an error status)."""
        if self.clients is not None:
            self.clients.answer(message, error)

    def _tell_time(self) -> None:
        """The sim time again, as a client subscribes: a simulation that stands still (paused, or
        ended) ticks no new time, and a client that joined after the last tick would see none."""
        server = getattr(self, "server", None)  # the SDK may call before start_server returned
        if self._sim_time and server is not None and self.clock.now_ns:
            server.broadcast_time(self.clock.now_ns)

    def _log_time(self) -> Callable[[], int] | None:
        """What stamps each message: a played log's timeline, else the sim clock, else the SDK's now."""
        if self._playback is not None:
            return self._playback.timeline.now_ns
        if self._sim_time:
            clock = self.clock
            return lambda: clock.now_ns
        return None

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        channel = self.context.channel(name, message_type, "foxglove")
        publisher = self._channels[channel.id()] = _Channel(
            channel, qos.latched, self._subscribers, self._log_time(), self._forget
        )
        return publisher

    def topics(self) -> list[str]:
        """The topics it publishes now (a publisher closed takes its topic away)."""
        return sorted(publisher.channel.topic() for publisher in list(self._channels.values()))

    def _forget(self, channel: _Channel) -> None:
        self._channels.pop(channel.id, None)
        self._subscribers.drop(channel.id)
        self.context.forget(channel.channel.topic())

    @property
    def url(self) -> str:
        """Where clients connect."""
        return f"ws://{self.settings.host}:{self.port}"

    def describe(self) -> str:
        app = "https://app.foxglove.dev?" + urlencode({"ds": "foxglove-websocket", "ds.url": self.url})
        checked = "" if self.front.gate.origins.checked else ", origin check off: any web page may connect"
        return f"Foxglove WebSocket server {self.url} (open {app}){checked}"

    def exposure(self) -> Exposure:
        return Exposure(f"Foxglove clients ({self.url})")

    def errors(self) -> Mapping[str, int]:
        """Client connections dropped or refused (the front's), and what clients published that no route got."""
        counts = self.front.errors()
        return counts | ({} if self.clients is None else self.clients.errors())

    def close(self) -> None:
        self.clock.unlisten(self._broadcast_time)
        self.front.close()
        self.server.stop()
