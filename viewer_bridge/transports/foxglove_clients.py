"""Foxglove clients that publish (the app's Publish and Teleop panels): their channels, their
messages handed to the routes, and the bridge's answers to each client alone.

The Foxglove WebSocket protocol (foxglove/ws-protocol, `docs/spec.md`): a server that lists the
`clientPublish` capability lets clients advertise channels of their own, a JSON text message
`{"op": "advertise", "channels": [{"id", "topic", "encoding", "schemaName", ...}]}` (ids are the
client's own, so two clients may both have a channel 1), withdrawn by `{"op": "unadvertise",
"channelIds": [...]}`; then each message is a binary frame `0x01 | u32 LE channel id | payload`,
encoded as advertised. The server may send a client `{"op": "status", "level": 0|1|2,
"message": ...}` at any time (2: error), which the app shows among its problems.

`ClientPublishing` reads along what clients send through the front
(viewer_bridge/transports/foxglove_front.py: the SDK still gets every byte; the SDK's Python API
would name a client by a number only and sends status messages to all). Each message on a client
channel whose topic a route's source pattern fully matches becomes one `Received`, with the
message's own type (`MessageType(schemaName as pkg/msg/Name, encoding)`) and its `Connection` as
origin, handed to every such route on the client's relay thread. What the bridge cannot take is
said to that client as an error status, not passed over in silence: a channel whose encoding is
not `cdr` or `json`, or whose topic no route reads (on advertise), an unreadable frame, and
(through `answer`, from `Transport.rejected`) a message a route refused, naming the field.

What it keeps per client is bounded: at most `max_channels` channels (an advertise past that is
refused with a status), all forgotten when the connection ends; and the statuses said lately, to
say each again only after SAY_AGAIN_SECONDS, are at most _SAID_KEPT, the oldest forgotten first.
"""

from __future__ import annotations

import json
import logging
import re
import struct
import threading
import time
from collections import Counter, OrderedDict
from dataclasses import dataclass
from typing import Any

from viewer_bridge.errors import BridgeError, Held
from viewer_bridge.transports.base import CDR, JSON, Deliver, MessageType, Received
from viewer_bridge.transports.foxglove_front import Connection
from viewer_bridge.transports.websocket_frames import BINARY, TEXT, Message

log = logging.getLogger(__name__)
CLIENT_ENCODINGS = (CDR, JSON)  # what the bridge reads from clients (serverInfo's supportedEncodings)
ERROR = 2  # a status message's level: 0 info, 1 warning, 2 error
_MESSAGE_DATA = 0x01  # a client's binary opcode: u32 LE channel id, then the payload
SAY_AGAIN_SECONDS = 5.0  # the same status to the same client, not more often (a panel publishing at 10 Hz)
_SAID_KEPT = 1000  # statuses remembered (client, text) to hold back repeats; then the oldest are forgotten
MAX_CLIENT_CHANNELS = 256  # channels one client may have advertised at once (foxglove.max_client_channels)
_SAID_CHARACTERS = 1000  # of a status's text and of its id: a client's topic or schema name may be megabytes


def ros_type_name(schema_name: str) -> str:
    """A ROS type as `pkg/msg/Name`; Foxglove's panels also say `pkg/Name` (ROS 1's form)."""
    parts = schema_name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 and all(parts) else schema_name


def _clipped(text: str) -> str:
    return text if len(text) <= _SAID_CHARACTERS else text[:_SAID_CHARACTERS] + "..."


def status(level: int, message: str, status_id: str) -> str:
    """A status message's JSON text."""
    return json.dumps({"op": "status", "level": level, "message": message, "id": status_id})


@dataclass(frozen=True, slots=True)
class ClientChannel:
    """A channel a client advertised: where it publishes, and the routes that read it (none:
    refused, with the reason said to the client)."""

    id: int
    topic: str
    message_type: MessageType
    routes: tuple[Deliver, ...]


class ClientPublishing:
    """The channels clients advertise and the messages they publish on them (a front's `Reader`)."""

    def __init__(self, max_channels: int = MAX_CLIENT_CHANNELS) -> None:
        self.max_channels = max_channels
        self._subscriptions: list[tuple[re.Pattern[str], Deliver]] = []
        self._channels: dict[Connection, dict[int, ClientChannel]] = {}
        # when each status was last said to each client, the least recently said first
        self._said: OrderedDict[tuple[Connection, str], float] = OrderedDict()
        self._errors: Counter[str] = Counter()
        self._logged_deep: set[Connection] = set()  # clients whose too-deep JSON was logged (once each)
        self._lock = threading.Lock()

    def subscribe(self, pattern: str, deliver: Deliver) -> None:
        """Deliver each message on a client channel whose topic fully matches `pattern`."""
        self._subscriptions.append((re.compile(pattern), deliver))

    def errors(self) -> dict[str, int]:
        """What clients sent that no route got, by kind (each also said to its client)."""
        with self._lock:
            return dict(self._errors)

    def remembered(self) -> tuple[int, int]:
        """What it keeps of its clients: (channels they advertise, statuses said to them recently)."""
        with self._lock:
            return sum(map(len, self._channels.values())), len(self._said)

    # --- a front's Reader: called on each client's relay thread

    def message(self, connection: Connection, message: Message) -> None:
        if message.skipped is not None:
            self._refuse(
                connection, "client_message_unread", "-", f"a message was not read: {message.skipped}"
            )
        elif message.opcode == TEXT:
            self._control(connection, message.payload)
        elif (
            message.opcode == BINARY
            and message.payload[:1] == bytes([_MESSAGE_DATA])
            and len(message.payload) >= 5
        ):
            (channel_id,) = struct.unpack_from("<I", message.payload, 1)
            self._publish(connection, channel_id, message.payload[5:])

    def closed(self, connection: Connection) -> None:
        with self._lock:
            self._channels.pop(connection, None)
            self._logged_deep.discard(connection)
            for key in [key for key in self._said if key[0] is connection]:
                del self._said[key]

    # --- the answer to a message a route refused

    def answer(self, received: Received, error: BridgeError) -> None:
        """Say to the client that sent `received` why a route refused it."""
        if not isinstance(received.origin, Connection):
            return
        reason = (error.reason if isinstance(error, Held) else str(error)).removeprefix(
            f"{received.channel}: "
        )
        what = f" ({received.message_type})" if received.message_type is not None else ""
        self._say(received.origin, received.channel, f"{received.channel}{what}: refused: {reason}")

    # --- what the client sent

    def _control(self, connection: Connection, payload: bytes) -> None:
        try:
            control = json.loads(payload)
        except ValueError:  # not JSON: the SDK answers it
            return
        except RecursionError:  # nested deeper than Python's reader goes: no client's control message
            self._too_deep(connection)
            return
        if not isinstance(control, dict):
            return
        if control.get("op") == "advertise" and isinstance(control.get("channels"), list):
            for advertised in control["channels"]:
                self._advertise(connection, advertised)
        elif control.get("op") == "unadvertise" and isinstance(control.get("channelIds"), list):
            with self._lock:
                channels = self._channels.get(connection, {})
                for channel_id in control["channelIds"]:
                    if isinstance(channel_id, int):
                        channels.pop(channel_id, None)

    def _too_deep(self, connection: Connection) -> None:
        """A text message nested too deep to read: refused (counted, said to the client as any
        unread message), and logged once per client, never as a traceback."""
        self._refuse(connection, "client_message_unread", "-",
                     "a message was not read: JSON nested deeper than the bridge reads")  # fmt: skip
        with self._lock:
            first = connection not in self._logged_deep
            if first:
                self._logged_deep.add(connection)
        if first:
            log.warning("%s sent JSON nested deeper than the bridge reads: refused (said once per client; "
                        "each is counted as client_message_unread)", connection)  # fmt: skip

    def _advertise(self, connection: Connection, advertised: Any) -> None:
        fields = advertised if isinstance(advertised, dict) else {}
        channel_id, topic = fields.get("id"), fields.get("topic")
        encoding, schema_name = fields.get("encoding"), fields.get("schemaName")
        if not (isinstance(channel_id, int) and isinstance(topic, str)):
            return  # not a channel: the SDK refuses it
        message_type = MessageType(
            ros_type_name(schema_name if isinstance(schema_name, str) else ""), str(encoding)
        )
        routes = tuple(deliver for pattern, deliver in self._subscriptions if pattern.fullmatch(topic))
        channel = ClientChannel(
            channel_id, topic, message_type, routes if encoding in CLIENT_ENCODINGS else ()
        )
        if not self._keep(connection, channel):
            # One text for every channel past the limit: said once, however many were advertised.
            self._refuse(connection, "client_channel_limit", "-",
                         f"a channel was refused: a client may have at most {self.max_channels} channels "
                         "advertised (foxglove.max_client_channels); unadvertise some first")  # fmt: skip
            return
        if encoding not in CLIENT_ENCODINGS:
            self._refuse(connection, "client_channel_refused", topic,
                         f"{topic}: encoding {encoding!r} is not read by this bridge (it reads "
                         f"{' or '.join(CLIENT_ENCODINGS)}); its messages are dropped")  # fmt: skip
        elif not routes:
            patterns = ", ".join(pattern.pattern for pattern, _ in self._subscriptions) or "none"
            self._refuse(connection, "client_channel_refused", topic,
                         f"{topic} ({message_type}): no route of this bridge reads it (the topics routes "
                         f"read: {patterns}); its messages are dropped")  # fmt: skip

    def _keep(self, connection: Connection, channel: ClientChannel) -> bool:
        """Hold `channel` as one of `connection`'s (an id advertised again is replaced); False
        when that would be more than `max_channels`."""
        with self._lock:
            channels = self._channels.setdefault(connection, {})
            if channel.id not in channels and len(channels) >= self.max_channels:
                return False
            channels[channel.id] = channel
            return True

    def _publish(self, connection: Connection, channel_id: int, payload: bytes) -> None:
        with self._lock:
            channel = self._channels.get(connection, {}).get(channel_id)
        if channel is None:  # never advertised: the SDK says so to the client
            return
        if not channel.routes:  # refused on advertise, said then
            with self._lock:
                self._errors["client_message_dropped"] += 1
            return
        received = Received(channel.topic, payload, message_type=channel.message_type, origin=connection)
        for deliver in channel.routes:
            deliver(received)

    def _refuse(self, connection: Connection, kind: str, topic: str, text: str) -> None:
        with self._lock:
            self._errors[kind] += 1
        self._say(connection, topic, text)

    def _say(self, connection: Connection, topic: str, text: str) -> None:
        # what is kept and sent stays small, whatever the client sent
        text, topic = _clipped(text), _clipped(topic)
        now = time.monotonic()
        with self._lock:
            last = self._said.get((connection, text))
            if last is not None and now - last < SAY_AGAIN_SECONDS:
                return
            self._said[(connection, text)] = now
            self._said.move_to_end((connection, text))
            while len(self._said) > _SAID_KEPT:  # the least recently said is forgotten (it may be said again)
                self._said.popitem(last=False)
        if not connection.send_text(status(ERROR, f"viewer-bridge: {text}", f"viewer-bridge {topic}")):
            with self._lock:
                self._errors["status_unsent"] += 1
