"""Foxglove's live WebSocket protocol as a transport, through the official foxglove-sdk.

Publish only: each name a route publishes on is a Foxglove channel (protobuf, with the schema of
its `foxglove.*` type), served to browsers on `host:port` (127.0.0.1:8765 unless configured). A
Foxglove client that subscribes is counted (so lazy routes wake up), and a latched output's last
message is logged again when a client subscribes, so a client that connects after the load still
gets the scene (SceneUpdates are idempotent). Everything about the protocol is the SDK's.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable

import foxglove
from foxglove.websocket import ChannelView, Client, ServerListener
from pydantic import Field

from bridge.formats.foxglove import schema
from bridge.transports.base import (
    PROTOBUF,
    Deliver,
    MessageType,
    Publisher,
    Qos,
    Transport,
    TransportSettings,
    TransportUnavailable,
)


def foxglove_channel(topic: str, message_type: MessageType, context: foxglove.Context) -> foxglove.Channel:
    """A Foxglove channel of a `foxglove.*` protobuf type in `context` (a server's, or an MCAP file's)."""
    return foxglove.Channel(
        topic,
        schema=foxglove.Schema(name=message_type.name, encoding="protobuf", data=schema(message_type.name)),
        message_encoding="protobuf",
        context=context,
    )


class FoxgloveSettings(TransportSettings):
    host: str = "127.0.0.1"  # this machine only, unless you mean to serve other hosts
    port: int = Field(8765, ge=0, le=65535)  # 0: any free port (the start-up line says which)
    name: str = "viewer-bridge"


class _Channel:
    """A publisher on one Foxglove channel: its subscribers, and its last message when latched."""

    def __init__(self, channel: foxglove.Channel, latched: bool) -> None:
        self.channel = channel
        self.latched = latched
        self.last: bytes | None = None
        self.clients: set[int] = set()
        self._lock = threading.Lock()

    def publish(self, data: bytes) -> None:
        if self.latched:
            self.last = data
        self.channel.log(data)

    def subscriber_count(self) -> int:
        return len(self.clients)

    def subscribed(self, client: int) -> None:
        with self._lock:
            self.clients.add(client)
        if self.last is not None:  # the late client gets the current state; others see it again
            self.channel.log(self.last)

    def unsubscribed(self, client: int) -> None:
        with self._lock:
            self.clients.discard(client)


class _Listener(ServerListener):
    """Clients subscribing to and unsubscribing from channels (the SDK calls it on its threads)."""

    def __init__(self, channels: dict[int, _Channel]) -> None:
        self._channels = channels

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        found = self._channels.get(channel.id)
        if found is not None:
            found.subscribed(client.id)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        found = self._channels.get(channel.id)
        if found is not None:
            found.unsubscribed(client.id)


class FoxgloveTransport(Transport):
    """A Foxglove WebSocket server with a context (its channels) of its own."""

    Settings = FoxgloveSettings
    encodings = frozenset({PROTOBUF})
    settings: FoxgloveSettings

    def __init__(self, settings: FoxgloveSettings) -> None:
        super().__init__(settings)
        self._channels: dict[int, _Channel] = {}  # by Foxglove channel id
        self.context = foxglove.Context()
        try:
            self.server = foxglove.start_server(
                name=settings.name,
                host=settings.host,
                port=settings.port,
                context=self.context,
                server_listener=_Listener(self._channels),
            )
        except Exception as error:  # the SDK raises its own error types, e.g. for a port in use
            where = f"{settings.host}:{settings.port}"
            raise TransportUnavailable(
                f"the foxglove server cannot listen on {where} (foxglove.port): {error}"
            ) from None

    @classmethod
    def carries(cls, message_type: MessageType) -> bool:
        return super().carries(message_type) and message_type.name.startswith("foxglove.")

    @classmethod
    def check_source(cls, name: str) -> None:
        raise ValueError("the foxglove transport only publishes; it cannot be a route's source")

    def require(self, message_types: Iterable[MessageType]) -> None:
        for message_type in message_types:
            try:
                schema(message_type.name)
            except (ImportError, KeyError) as error:
                raise TransportUnavailable(
                    f"foxglove-schemas-protobuf has no {message_type.name} ({error})"
                ) from None

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        raise TransportUnavailable("the foxglove transport only publishes")

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        channel = foxglove_channel(name, message_type, self.context)
        publisher = self._channels[channel.id()] = _Channel(channel, qos.latched)
        return publisher

    def describe(self) -> str:
        return f"Foxglove WebSocket server ws://{self.settings.host}:{self.server.port} (open {self.server.app_url()})"

    def close(self) -> None:
        self.server.stop()
