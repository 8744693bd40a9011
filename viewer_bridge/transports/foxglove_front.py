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
  masks and any negotiated extension stay end to end between the client and the SDK);
- a request that offers `foxglove.websocket.v1` but not `foxglove.sdk.v1` reaches the SDK asking
  for `foxglove.sdk.v1`, and the SDK's answer reaches the client naming `foxglove.websocket.v1`
  again (a WebSocket client refuses an answer that names a subprotocol it did not offer).

What it costs: one more loopback hop for every frame of every client, since the listening port
cannot be shared with the SDK (bench/foxglove_live.py measures it).

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
import logging
import socket
import threading
from collections import Counter
from typing import Protocol

from viewer_bridge.errors import HandshakeError
from viewer_bridge.transports.websocket_frames import ClientMessages, Message, MessageEnds, text_frame

log = logging.getLogger(__name__)

SDK_SUBPROTOCOL = "foxglove.sdk.v1"
OLDER_NAMES = frozenset({"foxglove.websocket.v1"})  # the same protocol under the name it had first
MAX_HEAD = 64 * 1024  # an HTTP head longer than this is not a WebSocket handshake
HANDSHAKE_SECONDS = 10.0  # a client that has not finished its request by then is dropped
CHUNK = 256 * 1024  # bytes relayed per read; a 1000-link FrameTransforms frame is about 108 kB
MAX_CLIENT_MESSAGE = 64 * 1024 * 1024  # a client's message read along up to this size (the SDK's own limit is its affair)
INJECT_WAIT_SECONDS = 5.0  # a frame of ours waits this long for a client stream busy sending; then it is dropped
_PROTOCOL_HEADER = b"sec-websocket-protocol"


def subprotocols(head: bytes) -> list[str]:
    """The subprotocols an HTTP head names, in order, from all its `Sec-WebSocket-Protocol` lines."""
    names: list[str] = []
    for line in head.split(b"\r\n")[1:]:
        key, colon, value = line.partition(b":")
        if colon and key.strip().lower() == _PROTOCOL_HEADER:
            names += [name.strip() for name in value.decode("latin-1").split(",") if name.strip()]
    return names


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


def read_head(connection: socket.socket) -> tuple[bytes, bytes]:
    """An HTTP head up to its blank line, and whatever arrived after it in the same reads."""
    data = bytearray()
    while (end := data.find(b"\r\n\r\n")) < 0:
        if len(data) > MAX_HEAD:
            raise HandshakeError(f"an HTTP head longer than {MAX_HEAD} bytes")
        chunk = connection.recv(4096)
        if not chunk:
            raise HandshakeError(f"closed after {len(data)} bytes, before the end of its HTTP head")
        data += chunk
    return bytes(data[: end + 4]), bytes(data[end + 4 :])


def _address(address: tuple[str, int] | tuple[str, int, int, int]) -> str:
    return f"{address[0]}:{address[1]}"


def _shut_down(connection: socket.socket) -> None:
    """Shut both ways (a thread blocked on it wakes up), unless it is already gone."""
    with contextlib.suppress(OSError):
        connection.shutdown(socket.SHUT_RDWR)


class Connection:
    """One relayed client, as a `Reader` sees it: its address, and `send_text` to answer it alone."""

    def __init__(self, address: str, client: socket.socket) -> None:
        self.address = address
        self._client = client
        self._ends = MessageEnds()  # where the SDK's messages to this client end
        self._pending: list[bytes] = []  # frames of ours waiting for the end of the SDK's message under way
        self._lock = threading.Lock()  # one writer at a time on the client's socket

    def __repr__(self) -> str:
        return f"foxglove client {self.address}"

    def send_text(self, text: str) -> bool:
        """Put a text frame into this client's stream at the next end of one of the SDK's messages;
        False when it cannot (the stream stayed busy for INJECT_WAIT_SECONDS, or the client is gone)."""
        if not self._lock.acquire(timeout=INJECT_WAIT_SECONDS):
            return False
        try:
            if self._ends.between:
                self._client.sendall(text_frame(text))
            else:
                self._pending.append(text_frame(text))
            return True
        except OSError:
            return False
        finally:
            self._lock.release()

    def relay(self, chunk: memoryview) -> None:
        """Send a chunk of the SDK's stream on to the client, with any frame of ours that waited
        inserted where the SDK's message under way ends."""
        with self._lock:
            end = self._ends.feed(chunk)
            if self._pending and end is not None:
                self._client.sendall(chunk[:end])
                self._client.sendall(b"".join(self._pending))
                self._pending.clear()
                chunk = chunk[end:]
            self._client.sendall(chunk)


class Reader(Protocol):
    """What reads along the clients' messages (the front's caller): called on each client's thread."""

    def message(self, connection: Connection, message: Message) -> None:
        """A whole message `connection`'s client sent (already relayed to the SDK)."""

    def closed(self, connection: Connection) -> None:
        """`connection` has ended: forget it."""


class _Relay:
    """One client connection and its connection to the SDK, relayed both ways by two threads."""

    def __init__(self, client: socket.socket, sdk: socket.socket, connection: Connection | None = None) -> None:
        self.sockets = (client, sdk)
        self.connection = connection  # set when the client's messages are read along
        self._ended = 0
        self._lock = threading.Lock()

    def pump(
        self, source: socket.socket, target: socket.socket, reader: Reader | None = None, early: bytes = b""
    ) -> bool:
        """Copy `source` to `target` until `source` ends; True when both directions have ended.
        From the client with a `reader`, each whole message goes to it too (`early`: what the
        client sent with its handshake, relayed already); from the SDK with a `connection`,
        through it (frames of ours go in between messages)."""
        buffer = bytearray(CHUNK)
        view = memoryview(buffer)
        connection, to_client = self.connection, source is self.sockets[1]
        messages = ClientMessages(MAX_CLIENT_MESSAGE) if reader is not None else None
        if messages is not None and reader is not None and connection is not None:
            for message in messages.feed(early):
                _read(reader, connection, message)
        try:
            while received := source.recv_into(buffer):
                if to_client and connection is not None:
                    connection.relay(view[:received])
                else:
                    target.sendall(view[:received])
                if messages is not None and reader is not None and connection is not None:
                    for message in messages.feed(view[:received]):
                        _read(reader, connection, message)
            target.shutdown(socket.SHUT_WR)  # the other direction may still carry a close frame
        except OSError:  # a reset or a close on either side ends both directions
            self.abort()
        with self._lock:
            self._ended += 1
            return self._ended == 2

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


class SubprotocolFront:
    """Listens on `host:port` and relays every client to the SDK's server at 127.0.0.1:`sdk_port`.

    `rename`: serve clients that ask for an older name of the protocol (else the SDK answers them
    as it does: refused). `reader`: reads along every client's messages (see the module's doc).
    """

    def __init__(
        self, host: str, port: int, sdk_port: int, *, rename: bool = True, reader: Reader | None = None
    ) -> None:
        self._rename = rename
        self._reader = reader
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self._listener = socket.create_server((host, port), family=family)
        self.port: int = self._listener.getsockname()[1]
        self._sdk_port = sdk_port
        self._relays: set[_Relay] = set()
        self._lock = threading.Lock()
        self._errors: Counter[str] = Counter()  # dropped connections by kind
        self._thread = threading.Thread(target=self._accept, name="foxglove front", daemon=True)
        self._thread.start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self._listener.accept()
            except OSError:  # the listener was closed
                return
            threading.Thread(target=self._serve, args=(client,), name="foxglove front client", daemon=True).start()

    def _serve(self, client: socket.socket) -> None:
        try:
            sdk = socket.create_connection(("127.0.0.1", self._sdk_port), timeout=HANDSHAKE_SECONDS)
        except OSError as error:
            self._count("sdk_unreachable", error)
            client.close()
            return
        connection = None
        try:
            connection = Connection(_address(client.getpeername()), client) if self._reader is not None else None
        except OSError as error:  # gone already
            self._count("bad_handshake", error)
            client.close()
            sdk.close()
            return
        relay = _Relay(client, sdk, connection)
        with self._lock:
            self._relays.add(relay)
        try:
            offered, early, rest = self._handshake(client, sdk)
            # The SDK's log names the relay's own address for this client: say which is which.
            log.info("foxglove client %s (subprotocols %s) is %s to the SDK's server",
                     _address(client.getpeername()), ", ".join(offered) or "none", _address(sdk.getsockname()))  # fmt: skip
            if connection is not None:
                connection.relay(memoryview(rest))  # the SDK's first frames: from here on, its messages are tracked
            else:
                client.sendall(rest)
        except (HandshakeError, OSError) as error:
            self._count("bad_handshake", error)
            self._forget(relay)
            return
        for each in (client, sdk):
            each.settimeout(None)
            each.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # frames go out as they come
        threading.Thread(target=self._pump, args=(relay, sdk, client), name="foxglove front sdk", daemon=True).start()
        self._pump(relay, client, sdk, early)

    def _handshake(self, client: socket.socket, sdk: socket.socket) -> tuple[list[str], bytes, bytes]:
        """Pass the client's request on and the SDK's answer head back, renamed for an older name;
        the subprotocols the client offered, and what each side sent after its head."""
        client.settimeout(HANDSHAKE_SECONDS)
        request, early = read_head(client)
        older = older_name_asked(request) if self._rename else None
        # None: the SDK's own name, or none it knows: the SDK answers as it does.
        sdk.sendall((request if older is None else naming(request, SDK_SUBPROTOCOL)) + early)
        answer, rest = read_head(sdk)
        client.sendall(answer if older is None else naming(answer, older))
        return subprotocols(request), early, rest

    def _pump(self, relay: _Relay, source: socket.socket, target: socket.socket, early: bytes = b"") -> None:
        reader = self._reader if source is relay.sockets[0] else None  # the client's side is read along
        if relay.pump(source, target, reader, early):
            self._forget(relay)

    def _forget(self, relay: _Relay) -> None:
        with self._lock:
            self._relays.discard(relay)
        relay.close()
        if self._reader is not None and relay.connection is not None:
            try:
                self._reader.closed(relay.connection)
            except Exception:
                log.exception("forgetting %s failed", relay.connection)

    def _count(self, kind: str, error: Exception) -> None:
        with self._lock:
            self._errors[kind] += 1
        log.warning("foxglove client connection dropped (%s): %s", kind.replace("_", " "), error)

    def errors(self) -> dict[str, int]:
        """Connections dropped before they were relayed, by kind (`bad_handshake`, `sdk_unreachable`)."""
        with self._lock:
            return dict(self._errors)

    def close(self) -> None:
        """Stop listening and end every relayed connection."""
        _shut_down(self._listener)  # wakes the accepting thread
        self._listener.close()
        self._thread.join(timeout=5)
        with self._lock:
            relays = list(self._relays)
        for relay in relays:
            relay.abort()


__all__ = [
    "CHUNK",
    "HANDSHAKE_SECONDS",
    "INJECT_WAIT_SECONDS",
    "MAX_CLIENT_MESSAGE",
    "MAX_HEAD",
    "OLDER_NAMES",
    "Connection",
    "Reader",
    "SDK_SUBPROTOCOL",
    "SubprotocolFront",
    "log",
    "naming",
    "older_name_asked",
    "read_head",
    "subprotocols",
]
