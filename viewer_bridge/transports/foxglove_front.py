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
import json
import logging
import socket
import threading
from collections import Counter
from typing import Protocol

from viewer_bridge.errors import HandshakeError, HttpRefusal
from viewer_bridge.transports.origins import FOXGLOVE_APPS, OriginGate, Origins
from viewer_bridge.transports.websocket_frames import ClientMessages, Message, MessageEnds, text_frame

log = logging.getLogger(__name__)

SDK_SUBPROTOCOL = "foxglove.sdk.v1"
OLDER_NAMES = frozenset({"foxglove.websocket.v1"})  # the same protocol under the name it had first
MAX_HEAD = 64 * 1024  # an HTTP head longer than this is not a WebSocket handshake
HANDSHAKE_SECONDS = 10.0  # a client that has not finished its request by then is dropped
CHUNK = 256 * 1024  # bytes relayed per read; a 1000-link FrameTransforms frame is about 108 kB
MAX_CLIENT_MESSAGE = 16 * 1024 * 1024  # a client's message read along up to this size (foxglove.max_client_message_bytes)
MAX_CLIENTS = 32  # clients connected at once (foxglove.max_clients); one more is answered 503
INJECT_WAIT_SECONDS = 5.0  # a frame of ours waits this long for a client stream busy sending; then it is dropped
MAX_PENDING = 1024 * 1024  # bytes of our frames waiting for the end of one of the SDK's messages; more are dropped
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
    return [name.strip() for value in header_values(head, _PROTOCOL_HEADER) for name in value.split(",") if name.strip()]


def foxglove_gate(origins: Origins) -> OriginGate:
    """The origin check of the Foxglove server, whose log line names the setting to widen it."""
    return OriginGate(origins, "foxglove client", lambda origin: f"foxglove.allowed_origins: {json.dumps([origin])}")


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


def read_head(connection: Receiving) -> tuple[bytes, bytes]:
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
        False when it cannot (the stream stayed busy for INJECT_WAIT_SECONDS, MAX_PENDING bytes of
        ours wait already, or the client is gone)."""
        if not self._lock.acquire(timeout=INJECT_WAIT_SECONDS):
            return False
        try:
            frame = text_frame(text)
            if self._ends.between:
                self._client.sendall(frame)
            elif sum(map(len, self._pending)) + len(frame) > MAX_PENDING:
                return False
            else:
                self._pending.append(frame)
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
        self,
        source: socket.socket,
        target: socket.socket,
        reader: Reader | None = None,
        early: bytes = b"",
        max_message_bytes: int = MAX_CLIENT_MESSAGE,
    ) -> bool:
        """Copy `source` to `target` until `source` ends; True when both directions have ended.
        From the client with a `reader`, each whole message goes to it too (`early`: what the
        client sent with its handshake, relayed already; a message longer than
        `max_message_bytes` is handed over as skipped); from the SDK with a `connection`,
        through it (frames of ours go in between messages)."""
        buffer = bytearray(CHUNK)
        view = memoryview(buffer)
        connection, to_client = self.connection, source is self.sockets[1]
        messages = ClientMessages(max_message_bytes, "foxglove.max_client_message_bytes") if reader is not None else None
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
    """Listens on `host:port` and relays every client it admits to the SDK's server at
    127.0.0.1:`sdk_port`.

    `rename`: serve clients that ask for an older name of the protocol (else the SDK answers them
    as it does: refused). `reader`: reads along every client's messages (see the module's doc),
    each up to `max_message_bytes`. `origins`: the pages whose browsers may connect (default:
    loopback pages and Foxglove's app). `max_clients`: connected at once; one more gets 503.
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
    ) -> None:
        self._rename = rename
        self._reader = reader
        self.gate = foxglove_gate(Origins(trusted=FOXGLOVE_APPS) if origins is None else origins)
        self.max_clients = max_clients
        self.max_message_bytes = max_message_bytes
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self._listener = socket.create_server((host, port), family=family)
        self.port: int = self._listener.getsockname()[1]
        self._sdk_port = sdk_port
        self._relays: set[_Relay] = set()
        self._admitted = 0  # clients past the door, relayed or about to be: at most max_clients
        self._said_full = False  # the 503 is logged once
        self._lock = threading.Lock()
        self._errors: Counter[str] = Counter()  # dropped or refused connections by kind
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
        """Read the client's request, admit it or answer a refusal, then relay it to the SDK."""
        try:
            client.settimeout(HANDSHAKE_SECONDS)
            address = _address(client.getpeername())
            request, early = read_head(client)
        except (HandshakeError, OSError) as error:  # cut off, too long, too slow, or gone already
            self._count("bad_handshake", error)
            client.close()
            return
        if not self._admit(client, request):
            return
        try:
            sdk = socket.create_connection(("127.0.0.1", self._sdk_port), timeout=HANDSHAKE_SECONDS)
        except OSError as error:
            self._leave()
            self._count("sdk_unreachable", error)
            client.close()
            return
        connection = Connection(address, client) if self._reader is not None else None
        relay = _Relay(client, sdk, connection)
        with self._lock:
            self._relays.add(relay)
        try:
            offered, rest = self._handshake(client, sdk, request, early)
            # The SDK's log names the relay's own address for this client: say which is which.
            log.info("foxglove client %s (subprotocols %s) is %s to the SDK's server",
                     address, ", ".join(offered) or "none", _address(sdk.getsockname()))  # fmt: skip
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

    def _handshake(
        self, client: socket.socket, sdk: socket.socket, request: bytes, early: bytes
    ) -> tuple[list[str], bytes]:
        """Pass the client's request on and the SDK's answer head back, renamed for an older name;
        the subprotocols the client offered, and what the SDK sent after its head."""
        older = older_name_asked(request) if self._rename else None
        # None: the SDK's own name, or none it knows: the SDK answers as it does.
        sdk.sendall((request if older is None else naming(request, SDK_SUBPROTOCOL)) + early)
        answer, rest = read_head(sdk)
        client.sendall(answer if older is None else naming(answer, older))
        return subprotocols(request), rest

    def _pump(self, relay: _Relay, source: socket.socket, target: socket.socket, early: bytes = b"") -> None:
        reader = self._reader if source is relay.sockets[0] else None  # the client's side is read along
        if relay.pump(source, target, reader, early, self.max_message_bytes):
            self._forget(relay)

    def _forget(self, relay: _Relay) -> None:
        with self._lock:
            self._relays.discard(relay)
            self._admitted -= 1
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

    def clients(self) -> int:
        """Clients admitted and not yet gone."""
        with self._lock:
            return self._admitted

    def errors(self) -> dict[str, int]:
        """Connections dropped or refused before they were relayed, by kind (`bad_handshake`,
        `sdk_unreachable`, `origin_refused`, `too_many_clients`)."""
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
    "MAX_CLIENTS",
    "MAX_CLIENT_MESSAGE",
    "MAX_HEAD",
    "MAX_PENDING",
    "OLDER_NAMES",
    "Connection",
    "Reader",
    "Receiving",
    "SDK_SUBPROTOCOL",
    "SubprotocolFront",
    "foxglove_gate",
    "header_values",
    "http_response",
    "log",
    "naming",
    "older_name_asked",
    "origin_refusal",
    "read_head",
    "subprotocols",
]
