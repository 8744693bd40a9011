"""A front for the foxglove-sdk's WebSocket server that also admits `foxglove.websocket.v1` clients.

The SDK's server accepts one WebSocket subprotocol, `foxglove.sdk.v1`, and answers a client that
asks for any other with HTTP 400. Foxglove's own `@foxglove/ws-protocol` client, Lichtblick until
late 2025 and the tools built on them ask for `foxglove.websocket.v1`. Both names stand for the
same protocol (Foxglove says so; the SDK's protocol-v1 messages are those of ws-protocol's
specification, checked message by message): the same JSON messages (`serverInfo`, `advertise`,
`unadvertise`, `status`, `subscribe`, `unsubscribe`, ...) and the same binary frames, opcode first
(from the server 0x01 message data `u32 subscription id | u64 log time | payload`, 0x02 time,
0x03 service call response, 0x04 fetch asset response; from a client 0x01 message data, 0x02
service call request). So nothing after the handshake needs translating, and this front changes
the handshake only:

- the front listens on the public address; the SDK listens on 127.0.0.1 at a port of its own;
- every client connection is relayed to the SDK byte for byte, both ways (WebSocket frames, their
  masks and any negotiated extension stay end to end between the client and the SDK), but for
  one repair of a race in the SDK: a subscription it refused because it had not yet listed a
  channel it had already advertised is sent again, and its error status held back
  (`Resubscriptions`);
- a request that offers `foxglove.websocket.v1` but not `foxglove.sdk.v1` reaches the SDK asking
  for `foxglove.sdk.v1`, and the SDK's answer reaches the client naming `foxglove.websocket.v1`
  again (a WebSocket client refuses an answer that names a subprotocol it did not offer).

What it costs: one more loopback hop for every frame of every client, since the listening port
cannot be shared with the SDK (bench/foxglove_live.py measures it).

The front is also the server's door, so it always holds the public port (even when it renames
nothing and reads nothing along). Before a request reaches the SDK, the front checks it and
answers a refusal itself, with a complete HTTP/1.1 response, so that the SDK never sees it:

- a browser page of a foreign origin gets 403 (viewer_bridge/transports/origins.py says which
  origins pass: no `Origin` header, loopback pages, Foxglove's app, and `foxglove.allowed_origins`);
- one client more than `foxglove.max_clients` connected at once gets 503.

The front is also where the bridge answers one client alone. The SDK's Python API names a client
by a number only and sends status messages to every client; the front knows each connection. So
when it is given a `Reader`, it reads along what each client sends (after relaying it: the SDK
still sees every byte) and hands the reader each whole message with the `Connection` it came on,
whose `send_text` puts a text frame of the bridge's own into that client's stream from the SDK,
between two of the SDK's messages (viewer_bridge/transports/websocket_frames.py finds where they
end). The Foxglove transport reads clients' published messages this way
(viewer_bridge/transports/foxglove_clients.py).
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import os
import re
import resource
import selectors
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any, Protocol, TypeGuard, TypeVar

from viewer_bridge.errors import FrameLimitError, HandshakeError, HttpRefusal
from viewer_bridge.transports.origins import FOXGLOVE_APPS, OriginGate, Origins
from viewer_bridge.transports.sdk_tls import SdkCertificate, SdkLink
from viewer_bridge.transports.websocket_frames import TEXT, ClientMessages, Message, RelayedStream, text_frame

log = logging.getLogger(__name__)

SDK_SUBPROTOCOL = "foxglove.sdk.v1"
OLDER_NAMES = frozenset({"foxglove.websocket.v1"})  # the same protocol under the name it had first
MAX_HEAD = 64 * 1024  # an HTTP head longer than this is not a WebSocket handshake
HANDSHAKE_SECONDS = 10.0  # a client that has not finished its request by then is dropped (one deadline)
# requests read at once (connections not yet admitted); one more drops the oldest (`handshake_budget`)
MAX_HANDSHAKES = 128
FD_SHARE = 4  # ... and at most this share of the process's open-file limit
ACCEPTS_PER_TURN = 64  # connections accepted before the requests under way are read again
LISTEN_BACKLOG = 128  # connections the kernel holds for the front before it refuses more
ACCEPT_BACKOFF_SECONDS = 0.25  # the listener rests this long when files run out or accepting fails
SAY_EVERY_SECONDS = 10.0  # at most one log line of each kind of dropped connection this often
CHUNK = 256 * 1024  # bytes relayed per read; a 1000-link FrameTransforms frame is about 108 kB
# a client's message read along up to this size (foxglove.max_client_message_bytes)
MAX_CLIENT_MESSAGE = 16 * 1024 * 1024
MAX_CLIENTS = 32  # clients connected at once (foxglove.max_clients); one more is answered 503
# a frame of ours waits this long for a client stream busy sending; then it is dropped
INJECT_WAIT_SECONDS = 5.0
# bytes of our frames waiting for the end of one of the SDK's messages; more are dropped
MAX_PENDING = 1024 * 1024
# a text message of the SDK's read (held back until whole); longer: passed unread
MAX_SDK_TEXT = 8 * 1024 * 1024
MAX_SUBSCRIPTIONS = 4096  # subscriptions, and channels advertised, remembered per client (Resubscriptions)
RESUBSCRIBE_DELAYS = (0.0, 0.01, 0.05, 0.25, 1.0)  # seconds before each attempt to subscribe again
_UNKNOWN_CHANNEL = b"Unknown channel ID: "  # the SDK's words (ConnectedClient::on_subscribe)
_UNKNOWN_CHANNEL_TEXT = re.compile(r"Unknown channel ID: ([0-9]{1,10})")
_ERROR_LEVEL = 2  # a status's level: 0 info, 1 warning, 2 error
_V = TypeVar("_V")
_PROTOCOL_HEADER = b"sec-websocket-protocol"
_REASONS = {403: "Forbidden", 503: "Service Unavailable"}


def header_values(head: bytes, name: bytes) -> list[str]:
    """The values of every `name` line (lower case) of an HTTP head, in order, as latin-1 text."""
    values: list[str] = []
    for line in head.split(b"\r\n")[1:]:
        key, colon, value = line.partition(b":")
        if colon and key.strip().lower() == name:
            values.append(value.decode("latin-1").strip())
    return values


def subprotocols(head: bytes) -> list[str]:
    """The subprotocols an HTTP head names, in order, from all its `Sec-WebSocket-Protocol` lines."""
    return [
        name.strip()
        for value in header_values(head, _PROTOCOL_HEADER)
        for name in value.split(",")
        if name.strip()
    ]


def foxglove_gate(origins: Origins) -> OriginGate:
    """The origin check of the Foxglove server, whose log line names the setting to widen it."""
    return OriginGate(
        origins, "foxglove client", lambda origin: f"foxglove.allowed_origins: {json.dumps([origin])}"
    )


def origin_refusal(request: bytes, gate: OriginGate) -> HttpRefusal | None:
    """The 403 for a request whose `Origin` the gate refuses, or None."""
    return gate.refusal(header_values(request, b"origin"))


def http_response(refusal: HttpRefusal) -> bytes:
    """A whole HTTP/1.1 answer carrying a refusal: its status, the reason as plain text, and
    `Connection: close` (nothing follows on that connection)."""
    body = f"{refusal}\n".encode()
    head = (f"HTTP/1.1 {refusal.status} {_REASONS.get(refusal.status, 'Error')}\r\n"
            f"Content-Type: text/plain; charset=utf-8\r\nContent-Length: {len(body)}\r\n"
            "Connection: close\r\n\r\n")  # fmt: skip
    return head.encode("latin-1") + body


def naming(head: bytes, subprotocol: str) -> bytes:
    """`head` with its `Sec-WebSocket-Protocol` line(s) replaced by one naming `subprotocol` only."""
    lines = head.split(b"\r\n")
    kept = [line for line in lines if line.partition(b":")[0].strip().lower() != _PROTOCOL_HEADER]
    if len(kept) == len(lines):  # none to replace (a refusal, say): unchanged
        return head
    header = b"Sec-WebSocket-Protocol: " + subprotocol.encode("latin-1")
    return b"\r\n".join([kept[0], header, *kept[1:]])


def older_name_asked(request: bytes) -> str | None:
    """The older name a request asks for instead of `foxglove.sdk.v1`, or None (no renaming)."""
    offered = subprotocols(request)
    if SDK_SUBPROTOCOL in offered:
        return None
    return next((name for name in offered if name in OLDER_NAMES), None)


class Receiving(Protocol):
    """What an HTTP head is read from: a socket."""

    def recv(self, size: int, /) -> bytes: ...


class Stream(Protocol):
    """A relayed connection's end: a socket, or the TLS link to the SDK (`SdkLink`)."""

    def recv(self, size: int, /) -> bytes: ...
    def recv_into(self, buffer: bytearray | memoryview, /) -> int: ...
    def sendall(self, data: bytes | bytearray | memoryview, /) -> None: ...
    def shutdown(self, how: int, /) -> None: ...
    def close(self) -> None: ...
    def settimeout(self, seconds: float | None, /) -> None: ...
    def setsockopt(self, level: int, option: int, value: int, /) -> None: ...
    def getsockname(self) -> Any: ...


class RequestHead:
    """An HTTP head arriving in pieces, bounded in size (MAX_HEAD) and in time: whole by
    `deadline`, however slowly its bytes trickle in (one deadline for the head, not one per read)."""

    def __init__(self, deadline: float) -> None:
        self.deadline = deadline
        self._data = bytearray()

    def feed(self, chunk: bytes, now: float) -> tuple[bytes, bytes] | None:
        """Take the bytes read at `now` (b"": the peer closed): the head and what came after it
        once it is whole, else None; HandshakeError when it cannot become a head in time."""
        if not chunk:
            raise HandshakeError(f"closed after {len(self._data)} bytes, before the end of its HTTP head")
        if now > self.deadline:
            raise HandshakeError(f"its HTTP head was not whole within {HANDSHAKE_SECONDS:g} s")
        start = max(0, len(self._data) - 3)  # the blank line may straddle two reads
        self._data += chunk
        end = self._data.find(b"\r\n\r\n", start)
        if end < 0 or end + 4 > MAX_HEAD:
            if len(self._data) > MAX_HEAD:
                raise HandshakeError(f"an HTTP head longer than {MAX_HEAD} bytes")
            return None
        return bytes(self._data[: end + 4]), bytes(self._data[end + 4 :])


def read_head(connection: Receiving, seconds: float = HANDSHAKE_SECONDS) -> tuple[bytes, bytes]:
    """An HTTP head up to its blank line, and whatever arrived after it in the same reads, read
    with blocking reads (a socket's own timeout bounds each; `seconds` the whole head)."""
    head = RequestHead(time.monotonic() + seconds)
    while (found := head.feed(connection.recv(4096), time.monotonic())) is None:
        pass
    return found


def _address(address: tuple[str, int] | tuple[str, int, int, int]) -> str:
    return f"{address[0]}:{address[1]}"


def _shut_down(connection: Stream | socket.socket) -> None:
    """Shut both ways (a thread blocked on it wakes up), unless it is already gone."""
    with contextlib.suppress(OSError):
        connection.shutdown(socket.SHUT_RDWR)


class _Outbound:
    """One direction of a relayed connection, into which the front puts frames of its own, each
    where a message of the relayed stream ends (never inside one)."""

    def __init__(self, target: Stream, hold_text_bytes: int = 0) -> None:
        self._target = target
        self._stream = RelayedStream(hold_text_bytes)
        self._pending: list[bytes] = []  # frames of ours waiting for the end of the message under way
        self._lock = threading.Lock()  # one writer at a time on the target socket
        self.framed = True  # false: the stream is no WebSocket's, passed as it comes

    def insert(self, make: Callable[[], bytes | None]) -> bool:
        """Put the frame `make` returns (called while no byte of the stream moves; None: nothing to
        put) in at the stream's next message end; False when it cannot (the stream stayed busy for
        INJECT_WAIT_SECONDS, MAX_PENDING bytes of ours wait already, or the socket is gone)."""
        if not self._lock.acquire(timeout=INJECT_WAIT_SECONDS):
            return False
        try:
            frame = make()
            if frame is None:
                return True
            if self._stream.between:
                self._target.sendall(frame)
            elif sum(map(len, self._pending)) + len(frame) > MAX_PENDING:
                return False
            else:
                self._pending.append(frame)
            return True
        except OSError:
            return False
        finally:
            self._lock.release()

    def relay(self, chunk: memoryview, keep: Callable[[bytes], bool] | None = None) -> None:
        """Send a chunk of the relayed stream on, with any frame of ours that waited put in where a
        message ends; a text message held back whole goes on unless `keep` says no to its payload."""
        with self._lock:
            if not self.framed:
                self._target.sendall(chunk)
                return
            for piece in self._stream.feed(chunk, cut_first_end=bool(self._pending)):
                if piece.text is None or keep is None or keep(piece.text):
                    self._target.sendall(piece.data)
                if piece.ends_message and self._pending:
                    self._target.sendall(b"".join(self._pending))
                    self._pending.clear()


def _json_object(payload: bytes) -> dict[str, Any]:
    """A JSON text's object, or {} for anything else (what is malformed is the SDK's to answer)."""
    try:
        value = json.loads(payload)
    except (ValueError, RecursionError):
        return {}
    return value if isinstance(value, dict) else {}


def _ids(value: object) -> list[int]:
    """The ids (u32) of a JSON list, others left out."""
    return [each for each in value if _is_id(each)] if isinstance(value, list) else []


def _is_id(value: object) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 1 << 32


class Resubscriptions:
    """One client's subscriptions, sent to the SDK again when it refused one only because it had
    not yet listed a channel it had already advertised to that client.

    The SDK's order (foxglove-sdk, rust/foxglove/src/websocket/connected_client.rs, in 0.30.3 as
    on its main branch): `ConnectedClient::advertise_channels` sends the `advertise` message first
    and adds the channels to that client's channel map after it; `ConnectedClient::on_subscribe`
    drops each subscription whose channel is not in that map, answers the client with an error
    status "Unknown channel ID: N" and never calls the server listener's `on_subscribe`. A client
    that subscribes the moment it reads the advertise (Foxglove's app does) wins that race when
    the advertising thread is preempted between those two steps, as on a loaded machine: its
    panel stays empty, and a lazy route of ours never hears of its subscriber.

    So the front remembers, per client, the subscriptions it sends (subscription id -> channel id)
    and the channels the SDK advertised to it and did not unadvertise, at most MAX_SUBSCRIPTIONS
    of each (past that the oldest are forgotten); an unsubscribe forgets its subscriptions. When
    the SDK answers that status for a channel that is both, the front holds the status back
    (a whole message: the client's stream stays well formed) and sends the client's
    subscriptions of that channel again, as a subscribe op of its own between two of the client's
    messages, after the next of RESUBSCRIBE_DELAYS (the map is filled a moment later). The client
    never sees an error that was not its own; after the last attempt the status reaches it.

    Reading the SDK's stream for this costs little: only its text messages (JSON, rare) are read,
    up to MAX_SDK_TEXT (a longer one passes unread: its channels are not known as advertised);
    binary message data passes as views of the bytes received, never copied. The SDK's WebSocket
    library (tungstenite 0.29, through tokio-tungstenite, built without compression) negotiates
    no extension, so its frames have RSV1 clear; one that had it would pass unread.

    The SDK answers the same words to message data a client publishes on a client channel it has
    not advertised (`on_message_data`). Should that id also be a server channel the client
    subscribed to, the subscription is sent again (the SDK then warns that it is already
    subscribed) where the error would have been.
    """

    def __init__(self) -> None:
        self._subscriptions: dict[int, int] = {}  # subscription id -> channel id, oldest first
        self._attempts: dict[int, int] = {}  # subscription id -> times sent again
        self._advertised: dict[int, None] = {}  # channel ids advertised, oldest first (an ordered set)
        self._lock = threading.Lock()  # the client's thread writes, the SDK's thread reads

    def client_said(self, payload: bytes) -> None:
        """Read a text message of the client's: remember its subscriptions, forget those it ends."""
        if b'"subscribe"' not in payload and b'"unsubscribe"' not in payload:  # parsing only what can matter
            return
        message = _json_object(payload)
        with self._lock:
            if message.get("op") == "subscribe" and isinstance(message.get("subscriptions"), list):
                for entry in message["subscriptions"]:
                    if isinstance(entry, dict) and _is_id(entry.get("id")) and _is_id(entry.get("channelId")):
                        self._remember(self._subscriptions, entry["id"], entry["channelId"])
                        self._attempts.pop(entry["id"], None)
            elif message.get("op") == "unsubscribe":
                for subscription in _ids(message.get("subscriptionIds")):
                    self._subscriptions.pop(subscription, None)
                    self._attempts.pop(subscription, None)

    def server_said(self, payload: bytes) -> tuple[int, float] | None:
        """Read a text message of the SDK's to this client. For the status that refused a
        subscription of a channel advertised to it: the channel, and how long to wait before
        sending its subscriptions again (the status is then not passed on); else None."""
        if (
            b'"advertise"' not in payload
            and b'"unadvertise"' not in payload
            and _UNKNOWN_CHANNEL not in payload
        ):
            return None
        message = _json_object(payload)
        op = message.get("op")
        with self._lock:
            if op == "advertise" and isinstance(message.get("channels"), list):
                for channel in message["channels"]:
                    if isinstance(channel, dict) and _is_id(channel.get("id")):
                        self._remember(self._advertised, channel["id"], None)
            elif op == "unadvertise":
                for channel in _ids(message.get("channelIds")):
                    self._advertised.pop(channel, None)
            elif (
                op == "status"
                and message.get("level") == _ERROR_LEVEL
                and isinstance(message.get("message"), str)
            ):
                return self._retry(message["message"])
        return None

    def _retry(self, text: str) -> tuple[int, float] | None:
        found = _UNKNOWN_CHANNEL_TEXT.fullmatch(text)
        channel = int(found[1]) if found else -1
        if channel not in self._advertised:
            return None
        waiting = [each for each, subscribed in self._subscriptions.items() if subscribed == channel
                   and self._attempts.get(each, 0) < len(RESUBSCRIBE_DELAYS)]  # fmt: skip
        if not waiting:
            return None
        attempt = min(self._attempts.get(each, 0) for each in waiting)
        for each in waiting:
            self._attempts[each] = self._attempts.get(each, 0) + 1
        return channel, RESUBSCRIBE_DELAYS[attempt]

    def remembered(self) -> tuple[int, int]:
        """How many (subscriptions, channels advertised) it keeps, each at most MAX_SUBSCRIPTIONS."""
        with self._lock:
            return len(self._subscriptions), len(self._advertised)

    def subscribe_op(self, channel: int) -> tuple[str, int] | None:
        """The subscribe op of the client's subscriptions of `channel` it has not ended, and how
        many they are; None when it has ended them all."""
        with self._lock:
            entries = [{"id": each, "channelId": channel} for each, subscribed in self._subscriptions.items()
                       if subscribed == channel]  # fmt: skip
        if not entries:
            return None
        return json.dumps({"op": "subscribe", "subscriptions": entries}), len(entries)

    @staticmethod
    def _remember(kept: dict[int, _V], key: int, value: _V) -> None:
        """Keep `key` as the newest entry of `kept`, the oldest forgotten past MAX_SUBSCRIPTIONS."""
        kept.pop(key, None)
        kept[key] = value
        if len(kept) > MAX_SUBSCRIPTIONS:
            del kept[next(iter(kept))]


class Connection:
    """One relayed client, as a `Reader` sees it: its address, and `send_text` to answer it alone.
    Both directions of its bytes go through it: what the SDK sends to be read just enough for
    `Resubscriptions`, what the client sends for its subscriptions."""

    def __init__(
        self,
        address: str,
        client: socket.socket,
        sdk: Stream,
        tally: Callable[[str, int], None] | None = None,
    ) -> None:
        self.address = address
        self._to_client = _Outbound(client, MAX_SDK_TEXT)
        self._to_sdk = _Outbound(sdk)
        self._subscriptions = Resubscriptions()
        self._tally = tally

    @property
    def framed(self) -> bool:
        """False once the SDK did not upgrade the connection: its bytes and the client's pass unread."""
        return self._to_client.framed

    @framed.setter
    def framed(self, framed: bool) -> None:
        self._to_client.framed = self._to_sdk.framed = framed

    def __repr__(self) -> str:
        return f"foxglove client {self.address}"

    def send_text(self, text: str) -> bool:
        """Put a text frame into this client's stream at the next end of one of the SDK's messages;
        False when it cannot (the stream stayed busy for INJECT_WAIT_SECONDS, MAX_PENDING bytes of
        ours wait already, or the client is gone)."""
        frame = text_frame(text)
        return self._to_client.insert(lambda: frame)

    def relay(self, chunk: memoryview) -> None:
        """Send a chunk of the SDK's stream on to the client (frames of ours go in between its
        messages; a status of a subscription the SDK refused too early is held back)."""
        self._to_client.relay(chunk, self._passes)

    def forward(self, chunk: memoryview, read: list[Message]) -> None:
        """Send a chunk of the client's stream on to the SDK; `read`: the messages it completed
        (read before the bytes go on, so that the SDK cannot answer a subscription not yet known)."""
        for message in read:
            if message.opcode == TEXT and message.skipped is None:
                self._subscriptions.client_said(message.payload)
        self._to_sdk.relay(chunk)

    def _passes(self, text: bytes) -> bool:
        """Whether a text message of the SDK's goes on to the client (see `Resubscriptions`)."""
        retry = self._subscriptions.server_said(text)
        if retry is None:
            return True
        # On a thread of its own: the SDK's stream to the client never waits for the client's to the SDK.
        timer = threading.Timer(retry[1], self._resubscribe, args=(retry[0],))
        timer.daemon = True
        timer.start()
        return False

    def _resubscribe(self, channel: int) -> None:
        sent = 0

        # asked while the client's stream stands still: never after its unsubscribe
        def frame() -> bytes | None:
            nonlocal sent
            op = self._subscriptions.subscribe_op(channel)
            if op is None:
                return None
            text, sent = op
            return text_frame(text, mask=os.urandom(4))  # a client's frame: masked

        if self._to_sdk.insert(frame) and sent:
            log.debug("%s: the SDK refused a subscription of channel %d it had advertised but not yet listed; "
                      "sent again", self, channel)  # fmt: skip
            if self._tally is not None:
                self._tally("resubscribed", sent)


class Reader(Protocol):
    """What reads along the clients' messages (the front's caller): called on each client's thread."""

    def message(self, connection: Connection, message: Message) -> None:
        """A whole message `connection`'s client sent (already relayed to the SDK)."""

    def closed(self, connection: Connection) -> None:
        """`connection` has ended: forget it."""


class _Relay:
    """One client connection and its connection to the SDK, relayed both ways by two threads."""

    def __init__(self, client: socket.socket, sdk: Stream, connection: Connection) -> None:
        self.sockets: tuple[Stream, Stream] = (client, sdk)
        self.connection = connection
        self._ended = 0
        self._lock = threading.Lock()

    def pump(
        self,
        source: Stream,
        target: Stream,
        reader: Reader | None = None,
        early: bytes = b"",
        max_message_bytes: int = MAX_CLIENT_MESSAGE,
    ) -> bool:
        """Copy `source` to `target` through the connection until `source` ends; True when both
        directions have ended. From the client (`early` first: what it sent with its handshake),
        its text messages are read, and with a `reader` each whole message goes to it too (one
        longer than `max_message_bytes` handed over as skipped). FrameLimitError: the client's
        frames went past what they may cost (the caller lets it go)."""
        buffer = bytearray(CHUNK)
        view = memoryview(buffer)
        from_client = source is self.sockets[0]
        messages = ClientMessages(
            max_message_bytes, "foxglove.max_client_message_bytes", binary=reader is not None
        )
        try:
            if from_client and early:
                self._from_client(memoryview(early), messages, reader)
            while received := source.recv_into(buffer):
                if from_client:
                    self._from_client(view[:received], messages, reader)
                else:
                    self.connection.relay(view[:received])
            target.shutdown(socket.SHUT_WR)  # the other direction may still carry a close frame
        except OSError:  # a reset or a close on either side ends both directions
            self.abort()
        return self.ended()

    def ended(self) -> bool:
        """One direction has ended; True when it was the second."""
        with self._lock:
            self._ended += 1
            return self._ended == 2

    def _from_client(self, chunk: memoryview, messages: ClientMessages, reader: Reader | None) -> None:
        read = messages.feed(chunk) if self.connection.framed else []
        self.connection.forward(chunk, read)
        if reader is not None:
            for message in read:
                _read(reader, self.connection, message)

    def abort(self) -> None:
        """Wake both pumps (they see the connection end); the sockets close when both have."""
        for each in self.sockets:
            _shut_down(each)

    def close(self) -> None:
        for each in self.sockets:
            each.close()


def _read(reader: Reader, connection: Connection, message: Message) -> None:
    """Hand one message to the reader; its failure is a bug of ours, never the end of the relay."""
    try:
        reader.message(connection, message)
    except Exception:
        log.exception("reading a message of %s failed", connection)


class _Pending:
    """A connection still sending its request: its head so far and its address."""

    def __init__(self, address: str, deadline: float) -> None:
        self.address = address
        self.head = RequestHead(deadline)


def handshake_budget(most: int = MAX_HANDSHAKES) -> int:
    """Requests read at once: `most`, and at most 1/FD_SHARE of this process's open-file limit
    (each is a file until it is admitted or dropped)."""
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    return most if soft == resource.RLIM_INFINITY else max(1, min(most, soft // FD_SHARE))


class SubprotocolFront:
    """Listens on `host:port` and relays every client it admits to the SDK's server at
    127.0.0.1:`sdk_port` (over TLS with the SDK's `certificate` when given: viewer_bridge/transports/sdk_tls.py).

    `rename`: serve clients that ask for an older name of the protocol (else the SDK answers them
    as it does: refused). `reader`: reads along every client's messages (see the module's doc),
    each up to `max_message_bytes`. `origins`: the pages whose browsers may connect (default:
    loopback pages and Foxglove's app). `max_clients`: connected at once; one more gets 503.

    One thread accepts connections and reads the requests of all those still sending theirs
    (`max_handshakes` at once, see `handshake_budget`: one more drops the oldest; each whole
    within HANDSHAKE_SECONDS, else dropped), so a crowd of slow clients holds neither threads nor
    more files than that; an admitted client gets two threads, for as long as it stays. That
    thread survives every error (logged, counted, retried; out of files it backs off), and a
    watcher starts it again should it end anyway (said as an error).
    """

    def __init__(
        self,
        host: str,
        port: int,
        sdk_port: int,
        *,
        rename: bool = True,
        reader: Reader | None = None,
        origins: Origins | None = None,
        max_clients: int = MAX_CLIENTS,
        max_message_bytes: int = MAX_CLIENT_MESSAGE,
        certificate: SdkCertificate | None = None,
        max_handshakes: int | None = None,
    ) -> None:
        self._rename = rename
        self._reader = reader
        self.gate = foxglove_gate(Origins(trusted=FOXGLOVE_APPS) if origins is None else origins)
        self.max_clients = max_clients
        self.max_message_bytes = max_message_bytes
        self.max_handshakes = handshake_budget() if max_handshakes is None else max_handshakes
        self._certificate = certificate
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self._listener = socket.create_server((host, port), family=family, backlog=LISTEN_BACKLOG)
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._sdk_port = sdk_port
        self._relays: set[_Relay] = set()
        self._pending: dict[socket.socket, _Pending] = {}  # the accepting thread's alone; oldest first
        self._admitted = 0  # clients past the door, relayed or about to be: at most max_clients
        self._said_full = False  # the 503 is logged once
        self._lock = threading.Lock()
        self._errors: Counter[str] = Counter()  # dropped or refused connections by kind
        self._last_said: dict[str, tuple[float, int]] = {}  # kind -> (when logged, counted since)
        self._resume_at = 0.0  # out of files: no accepting before this (time.monotonic)
        self._spare = _spare_file()  # given up to refuse one connection when files run out
        self._closing = threading.Event()
        self._thread = self._start_accepting()
        self._watcher = threading.Thread(target=self._watch, name="foxglove front watch", daemon=True)
        self._watcher.start()

    def _start_accepting(self) -> threading.Thread:
        thread = threading.Thread(target=self._accept, name="foxglove front", daemon=True)
        thread.start()
        return thread

    def _watch(self) -> None:
        """Start the accepting thread again should it end before `close` (a bug of ours: said)."""
        while True:
            self._thread.join()
            if self._closing.is_set():
                return
            log.error("the foxglove front's accepting thread ended: started again (a bug: please report it)")
            with self._lock:
                self._errors["accept_restarted"] += 1
            time.sleep(ACCEPT_BACKOFF_SECONDS)
            self._thread = self._start_accepting()

    def _accept(self) -> None:
        """New connections and the requests of those still sending theirs, on one selector; an
        error of any kind is logged, counted and retried after ACCEPT_BACKOFF_SECONDS."""
        with selectors.DefaultSelector() as selector:
            for pending in list(self._pending):  # kept across a restart
                selector.register(pending, selectors.EVENT_READ)
            listening = False
            while not self._closing.is_set():
                try:
                    now = time.monotonic()
                    if listening != (now >= self._resume_at):  # out of files: the listener rests
                        listening = not listening
                        if listening:
                            selector.register(self._listener, selectors.EVENT_READ)
                        else:
                            with contextlib.suppress(KeyError, ValueError):  # its registering failed
                                selector.unregister(self._listener)
                    ready = [key.fileobj for key, _ in selector.select(self._until_next(now))]
                    # requests first: one that came is read before more connections can push it out
                    for client in ready:
                        if client is not self._listener:
                            self._read_request(selector, client)  # type: ignore[arg-type]
                    if self._listener in ready:
                        self._accept_waiting(selector)
                    self._expire(selector, time.monotonic())
                except Exception as error:  # never the end of accepting: counted, said, tried again
                    if self._closing.is_set():
                        return
                    self._say("accept_error", f"accepting foxglove clients failed ({type(error).__name__}: "
                              f"{error}); trying again in {ACCEPT_BACKOFF_SECONDS} s")  # fmt: skip
                    self._resume_at = time.monotonic() + ACCEPT_BACKOFF_SECONDS

    def _until_next(self, now: float) -> float:
        """How long the selector may wait: until the first request's deadline or the end of a rest."""
        soonest = min((pending.head.deadline for pending in self._pending.values()), default=now + 1.0)
        if now < self._resume_at:
            soonest = min(soonest, self._resume_at)
        return min(1.0, max(0.0, soonest - now))

    def _accept_waiting(self, selector: selectors.BaseSelector) -> None:
        """Accept the connections waiting (a bounded number per turn); each one's request is
        read as it comes. Past `max_handshakes`, the oldest request still under way is dropped."""
        for _ in range(ACCEPTS_PER_TURN):
            try:
                client, address = self._listener.accept()
            except BlockingIOError:
                return
            except OSError as error:
                if error.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    self._out_of_files(error)
                    return
                raise
            if len(self._pending) >= self.max_handshakes:
                oldest = next(iter(self._pending))
                self._drop(selector, oldest)
                self._say("too_many_handshakes", f"a foxglove client's request under way dropped: "
                          f"{self.max_handshakes} connections were sending theirs at once")  # fmt: skip
            client.setblocking(False)
            self._pending[client] = _Pending(_address(address), time.monotonic() + HANDSHAKE_SECONDS)
            selector.register(client, selectors.EVENT_READ)

    def _out_of_files(self, error: OSError) -> None:
        """No file for a new connection: refuse one waiting (with the spare file, given up for
        it), say so (throttled) and rest the listener a moment; the waiting ones stay in the queue."""
        self._resume_at = time.monotonic() + ACCEPT_BACKOFF_SECONDS
        self._say("out_of_files", f"no file for a new foxglove client ({error}): connections wait or are "
                  "refused until files are free again (the open-file limit: ulimit -n)")  # fmt: skip
        if self._spare is None:
            return
        os.close(self._spare)
        with contextlib.suppress(OSError):
            refused, _ = self._listener.accept()
            refused.close()
        self._spare = _spare_file()

    def _read_request(self, selector: selectors.BaseSelector, client: socket.socket) -> None:
        """Read what came of one request; once whole, admit it (or answer a refusal) and relay it."""
        pending = self._pending[client]
        try:
            found = pending.head.feed(client.recv(4096), time.monotonic())
        except BlockingIOError:
            return
        except (HandshakeError, OSError) as error:  # cut off, too long, too slow, or gone already
            self._drop(selector, client)
            self._count("bad_handshake", error)
            return
        if found is None:
            return
        selector.unregister(client)
        del self._pending[client]
        request, early = found
        if not self._admit(client, request):  # a refusal's few bytes fit in the socket's buffer
            return
        client.setblocking(True)
        try:
            threading.Thread(target=self._serve, args=(client, pending.address, request, early),
                             name="foxglove front client", daemon=True).start()  # fmt: skip
        except RuntimeError as error:  # no thread to be had
            self._leave()
            client.close()
            self._count("no_thread", error)

    def _expire(self, selector: selectors.BaseSelector, now: float) -> None:
        """Drop the requests not whole by their deadline (the oldest are first)."""
        while self._pending:
            client, pending = next(iter(self._pending.items()))
            if pending.head.deadline >= now:
                return
            self._drop(selector, client)
            self._count("bad_handshake", HandshakeError(
                f"{pending.address}: its HTTP head was not whole within {HANDSHAKE_SECONDS:g} s"))  # fmt: skip

    def _drop(self, selector: selectors.BaseSelector, client: socket.socket) -> None:
        del self._pending[client]
        with contextlib.suppress(KeyError, ValueError):
            selector.unregister(client)
        client.close()

    def _connect_sdk(self) -> Stream:
        if self._certificate is None:
            return socket.create_connection(("127.0.0.1", self._sdk_port), timeout=HANDSHAKE_SECONDS)
        return SdkLink.open(self._sdk_port, self._certificate, HANDSHAKE_SECONDS)

    def _serve(self, client: socket.socket, address: str, request: bytes, early: bytes) -> None:
        """Relay an admitted client to the SDK (on a thread of its own)."""
        try:
            sdk = self._connect_sdk()
        except (HandshakeError, OSError) as error:
            self._leave()
            self._count("sdk_unreachable", error)
            client.close()
            return
        connection = Connection(address, client, sdk, self._tally)
        relay = _Relay(client, sdk, connection)
        with self._lock:
            self._relays.add(relay)
        try:
            client.settimeout(HANDSHAKE_SECONDS)
            sdk.settimeout(HANDSHAKE_SECONDS)
            offered, rest, upgraded = self._handshake(client, sdk, request)
            # The SDK's log names the relay's own address for this client: say which is which.
            log.info("foxglove client %s (subprotocols %s) is %s to the SDK's server",
                     address, ", ".join(offered) or "none", _address(sdk.getsockname()))  # fmt: skip
            if not upgraded:  # a refusal's body and whatever follows are no WebSocket frames
                connection.framed = False
            # the SDK's first frames: from here on, its messages are tracked
            connection.relay(memoryview(rest))
        except (HandshakeError, OSError) as error:
            self._count("bad_handshake", error)
            self._forget(relay)
            return
        for each in (client, sdk):
            each.settimeout(None)
            each.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # frames go out as they come
        try:
            threading.Thread(
                target=self._pump, args=(relay, sdk, client), name="foxglove front sdk", daemon=True
            ).start()
        except RuntimeError as error:  # no thread to be had: this client is not served
            self._count("no_thread", error)
            self._forget(relay)
            return
        self._pump(relay, client, sdk, early)

    def _admit(self, client: socket.socket, request: bytes) -> bool:
        """True, holding one of the `max_clients` places, for a request that may go on to the SDK;
        else the refusal is answered, counted and the connection closed."""
        refusal = origin_refusal(request, self.gate)
        if refusal is None:
            refusal = self._take_place()
        if refusal is None:
            return True
        with self._lock:
            self._errors[refusal.kind] += 1
        with contextlib.suppress(OSError):  # a client already gone needs no answer
            client.sendall(http_response(refusal))
            client.shutdown(socket.SHUT_WR)
        client.close()
        return False

    def _take_place(self) -> HttpRefusal | None:
        with self._lock:
            if self._admitted < self.max_clients:
                self._admitted += 1
                return None
            first, self._said_full = not self._said_full, True
        refusal = HttpRefusal(503, "too_many_clients", f"a foxglove client more than the {self.max_clients} connected "
                              "at once refused (503): raise foxglove.max_clients to serve more")  # fmt: skip
        if first:
            log.warning("%s (said once; each is counted as too_many_clients)", refusal)
        return refusal

    def _leave(self) -> None:
        with self._lock:
            self._admitted -= 1

    def _handshake(self, client: socket.socket, sdk: Stream, request: bytes) -> tuple[list[str], bytes, bool]:
        """Pass the client's request on and the SDK's answer head back, renamed for an older name;
        the subprotocols the client offered, what the SDK sent after its head, and whether it
        upgraded the connection (101). (What the client sent after its request, `early`, goes on
        through its relay.)"""
        older = older_name_asked(request) if self._rename else None
        # None: the SDK's own name, or none it knows: the SDK answers as it does.
        sdk.sendall(request if older is None else naming(request, SDK_SUBPROTOCOL))
        answer, rest = read_head(sdk)
        client.sendall(answer if older is None else naming(answer, older))
        return subprotocols(request), rest, answer.split(b" ", 2)[1:2] == [b"101"]

    def _pump(self, relay: _Relay, source: Stream, target: Stream, early: bytes = b"") -> None:
        reader = self._reader if source is relay.sockets[0] else None  # the client's side is read along
        try:
            ended = relay.pump(source, target, reader, early, self.max_message_bytes)
        except FrameLimitError as error:  # a client past what its frames may cost: it is let go
            self._count("frame_limit", error)
            relay.abort()
            ended = relay.ended()
        if ended:
            self._forget(relay)

    def _forget(self, relay: _Relay) -> None:
        with self._lock:
            self._relays.discard(relay)
            self._admitted -= 1
        relay.close()
        if self._reader is not None:
            try:
                self._reader.closed(relay.connection)
            except Exception:
                log.exception("forgetting %s failed", relay.connection)

    def _count(self, kind: str, error: Exception) -> None:
        self._say(kind, f"foxglove client connection dropped ({kind.replace('_', ' ')}): {error}")

    def _say(self, kind: str, text: str) -> None:
        """Count one of `kind` and log `text`: the first at once, then at most one line of that
        kind per SAY_EVERY_SECONDS (a crowd of bad connections is a few lines), with how many
        went unsaid meanwhile."""
        now = time.monotonic()
        with self._lock:
            self._errors[kind] += 1
            last, unsaid = self._last_said.get(kind, (-SAY_EVERY_SECONDS, 0))
            if now - last < SAY_EVERY_SECONDS:
                self._last_said[kind] = (last, unsaid + 1)
                return
            self._last_said[kind] = (now, 0)
        more = f" ({unsaid} more like it since the last said, counted as {kind})" if unsaid else ""
        log.warning("%s%s", text, more)

    def _tally(self, kind: str, count: int) -> None:
        """Count what the front did for a client that is no error of the client's (no log line)."""
        with self._lock:
            self._errors[kind] += count

    def clients(self) -> int:
        """Clients admitted and not yet gone."""
        with self._lock:
            return self._admitted

    def handshakes(self) -> int:
        """Connections still sending their request."""
        return len(self._pending)

    def errors(self) -> dict[str, int]:
        """Connections dropped or refused before they were relayed, by kind (`bad_handshake`,
        `too_many_handshakes`, `sdk_unreachable`, `origin_refused`, `too_many_clients`,
        `no_thread`), clients let go (`frame_limit`), the accepting thread's troubles
        (`out_of_files`, `accept_error`, `accept_restarted`); and `resubscribed`: clients'
        subscriptions the SDK refused before it had listed their channel, sent again
        (`Resubscriptions`)."""
        with self._lock:
            return dict(self._errors)

    def close(self) -> None:
        """Stop listening and end every relayed connection."""
        self._closing.set()
        self._thread.join(timeout=5)  # it sees `_closing` within a second
        self._listener.close()
        for client in list(self._pending):
            client.close()
        self._pending.clear()
        if self._spare is not None:
            os.close(self._spare)
            self._spare = None
        with self._lock:
            relays = list(self._relays)
        for relay in relays:
            relay.abort()


def _spare_file() -> int | None:
    """A file held in reserve, to be given up when files run out; None when there is none."""
    try:
        return os.open(os.devnull, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
