"""WebSocket framing (RFC 6455, section 5) as far as a relay that reads along needs it.

A frame is: a byte `FIN | RSV1-3 | opcode`, a byte `MASK | length` (126: a 16-bit length follows,
127: a 64-bit one, both big-endian), the 4-byte masking key when MASK is set (every frame a client
sends; none a server sends), then the payload, XORed with the key byte by byte when masked. A
message is one data frame (opcode 1 text, 2 binary) with FIN set, or such a frame without FIN
followed by continuation frames (opcode 0), the last with FIN. Control frames (opcode 8 close,
9 ping, 10 pong) are never fragmented and may come between the fragments of a message.

Two readers of a byte stream fed in whatever chunks the socket gives: `ClientMessages` returns
each complete data message a client sent, unmasked; `RelayedStream` cuts a stream being relayed
where its messages end, so that a frame of the relay's own (`text_frame`) can go between two of
them, and holds back short text messages whole, so that the relay can read one and drop it.
"""

from __future__ import annotations

from dataclasses import dataclass

from viewer_bridge.errors import FrameLimitError

CONTINUATION, TEXT, BINARY = 0, 1, 2
# frames of one message (its fragments, and control frames between them): no client sends more
# (a browser never fragments); each costs the reader as much as a byte of payload a thousand times
MAX_FRAGMENTS = 1024
_FIN, _RSV1, _MASKED = 0x80, 0x40, 0x80


@dataclass(frozen=True, slots=True)
class Message:
    """One complete data message: `opcode` TEXT or BINARY, and its unmasked payload; or, with
    `skipped` saying why, one that could not be read (its payload empty)."""

    opcode: int
    payload: bytes
    skipped: str | None = None


@dataclass(frozen=True, slots=True)
class Piece:
    """Bytes of a relayed stream, to send on as they are, in order."""

    data: bytes | memoryview
    ends_message: bool  # the stream's bytes up to here end with a whole message: a frame may follow
    # when `data` is a text message held back whole: its payload (it may be dropped)
    text: bytes | None = None


@dataclass(frozen=True, slots=True)
class _Header:
    fin: bool
    rsv1: bool
    opcode: int
    mask: bytes  # b"" when unmasked
    length: int
    size: int  # bytes of the header itself


def _header(data: bytes | bytearray) -> _Header | None:
    """The header at the start of `data`, or None while `data` holds only part of it."""
    if len(data) < 2:
        return None
    first, second = data[0], data[1]
    length, size = second & 0x7F, 2
    if length == 126:
        size = 4
    elif length == 127:
        size = 10
    masked = bool(second & _MASKED)
    if len(data) < size + 4 * masked:
        return None
    if size > 2:
        length = int.from_bytes(data[2:size], "big")
    mask = bytes(data[size : size + 4]) if masked else b""
    return _Header(bool(first & _FIN), bool(first & _RSV1), first & 0x0F, mask, length, size + len(mask))


def unmask(payload: bytes | bytearray, mask: bytes) -> bytes:
    """`payload` XORed with the 4-byte `mask` repeated (as one big integer: no loop per byte)."""
    if not mask or not payload:
        return bytes(payload)
    count = len(payload)
    key = (mask * (count // 4 + 1))[:count]
    return (int.from_bytes(payload, "little") ^ int.from_bytes(key, "little")).to_bytes(count, "little")


class ClientMessages:
    """The data messages of a client's byte stream (masked frames), fragments joined.

    `feed(chunk)` returns the messages that chunk completed. A message longer than `max_bytes`
    or compressed (RSV1, a negotiated extension) is skipped whole, its bytes dropped as they
    come; it is returned once as a `Message` whose `skipped` says why (naming `limit_name`, the
    setting of `max_bytes`, when it was too long). A message's length counts the header of each
    frame after its first too, so that empty continuation frames are no free ride; a message in
    more than MAX_FRAGMENTS frames raises FrameLimitError (its client is let go: skipping it
    frame by frame would still cost a parse per frame). With `binary` false, binary messages are
    dropped as they come, never returned (a reader of text messages only). What it holds is
    bounded: at most `max_bytes` of a message under way, in at most MAX_FRAGMENTS parts, and
    one chunk.
    """

    def __init__(self, max_bytes: int, limit_name: str = "", *, binary: bool = True) -> None:
        self.max_bytes = max_bytes
        self._read = (TEXT, BINARY) if binary else (TEXT,)
        self._too_long = f"longer than {max_bytes} bytes" + (f" ({limit_name})" if limit_name else "")
        self._buffer = bytearray()  # bytes not yet consumed: a partial header or payload
        self._opcode: int | None = None  # the data message under way (None: none, or skipped)
        self._parts: list[bytes] = []
        self._joined = 0
        self._drop = 0  # payload bytes of a skipped frame still to come
        self._fragments = 0  # frames of the message under way (0: none under way)

    @property
    def held_bytes(self) -> int:
        """The bytes it holds, not yet consumed (a partial header or payload)."""
        return len(self._buffer)

    def feed(self, chunk: bytes | memoryview) -> list[Message]:
        self._buffer += chunk
        messages: list[Message] = []
        while True:
            if self._drop:
                taken = min(self._drop, len(self._buffer))
                del self._buffer[:taken]
                self._drop -= taken
                if self._drop:
                    break
            header = _header(self._buffer)
            if header is None:
                break
            end = header.size + header.length
            if header.opcode >= 8:  # control: nothing a relay reads along, dropped as it comes
                self._count_fragment(header)
                del self._buffer[: header.size]
                self._drop = header.length
                continue
            if header.opcode != CONTINUATION:  # a new message (opcodes 3 to 7 are reserved: dropped)
                self._opcode = header.opcode if header.opcode in self._read else None
                self._parts, self._joined = [], 0
                if header.rsv1 and self._opcode is not None:
                    messages.append(
                        Message(self._opcode, b"", "compressed (an extension the bridge does not read)")
                    )
                    self._opcode = None
            cost = header.length + (header.size if header.opcode == CONTINUATION else 0)
            if self._opcode is not None and self._joined + cost > self.max_bytes:
                messages.append(Message(self._opcode, b"", self._too_long))
                self._opcode = None
            if self._opcode is None:  # skipped (or a continuation of nothing): drop its payload
                self._count_fragment(header)
                del self._buffer[: header.size]
                self._drop = header.length
                self._parts = []
                continue
            if len(self._buffer) < end:
                break
            self._parts.append(unmask(self._buffer[header.size : end], header.mask))
            self._joined += cost
            self._count_fragment(header)
            del self._buffer[:end]
            if header.fin:
                messages.append(Message(self._opcode, b"".join(self._parts)))
                self._opcode, self._parts = None, []
        return messages

    def _count_fragment(self, header: _Header) -> None:
        """Count a frame as it is consumed (once, however many chunks its payload takes) toward
        the message under way (a data frame without FIN starts one; its final fragment ends it);
        FrameLimitError past MAX_FRAGMENTS."""
        if header.opcode in (TEXT, BINARY) or 2 < header.opcode < 8:
            self._fragments = 0 if header.fin else 1
        elif self._fragments:
            self._fragments += 1
            if self._fragments > MAX_FRAGMENTS:
                raise FrameLimitError(f"a message in more than {MAX_FRAGMENTS} frames")
            if header.opcode == CONTINUATION and header.fin:
                self._fragments = 0


class RelayedStream:
    """A relayed byte stream, fed chunk by chunk, cut into the pieces a relay sends on in order.

    Most bytes pass as views of the chunk they came in, never copied (binary message data is most
    of the traffic). A piece is cut where a message ends when the relay asks (`cut_first_end`: a
    frame of its own waits to go in there), and around each text frame this reader holds back:
    one with FIN, unmasked and uncompressed (no RSV1), starting a message, of at most
    `hold_bytes`. Such a frame is returned whole, with its payload, once its last byte has come:
    the relay reads it and may drop it (a whole message: what the other end gets stays well
    formed). A frame header cut by a chunk's end is held back until the rest of it comes, so that
    a held frame is never partly sent.
    """

    def __init__(self, hold_bytes: int = 0) -> None:
        self.hold_bytes = hold_bytes
        self._header = bytearray()  # the header under way, cut by a chunk's end
        self._carried = 0  # of its bytes, those that came in earlier chunks
        self._left = 0  # payload bytes of the current frame still to come
        self._held: bytearray | None = None  # the text frame held back, as far as it has come
        self._held_header = 0  # the size of its header
        self._in_message = False  # between the fragments of a data message

    @property
    def between(self) -> bool:
        """True when the pieces returned so far end with a whole message (a frame may go in now)."""
        return not self._in_message and (self._left == 0 or self._held is not None)

    @property
    def held_bytes(self) -> int:
        """The bytes it holds back: a text frame as far as it has come, and a header cut short."""
        return len(self._held or b"") + len(self._header)

    def feed(self, chunk: memoryview, cut_first_end: bool = False) -> list[Piece]:
        """Consume `chunk`; its bytes in pieces (those held back come in a later call's pieces)."""
        pieces: list[Piece] = []
        self._carried = len(self._header)
        start = header_at = at = 0  # start: the first byte in no piece yet; header_at: where the header began
        cut = not cut_first_end  # True once no cut is wanted
        size = len(chunk)
        while at < size:
            if self._left:
                taken = min(self._left, size - at)
                if self._held is not None:
                    self._held += chunk[at : at + taken]
                self._left -= taken
                at += taken
            else:
                if not self._header:
                    header_at = at
                taken = min(self._header_bytes_needed(), size - at)
                self._header += chunk[at : at + taken]
                at += taken
                header = _header(self._header)
                if header is None or len(self._header) < header.size:
                    continue
                start = self._begin_frame(header, chunk, start, header_at, at, pieces)
            if self._left == 0 and not self._header:  # a frame's last byte
                if self._held is not None:
                    pieces.append(Piece(bytes(self._held), True, bytes(self._held[self._held_header :])))
                    self._held, start = None, at
                elif not cut and not self._in_message:
                    pieces.append(Piece(chunk[start:at], True))
                    start, cut = at, True
        end = start if self._held is not None else header_at if self._header else size
        if end > start:
            pieces.append(Piece(chunk[start:end], not self._in_message and self._left == 0))
        return pieces

    def _begin_frame(
        self, header: _Header, chunk: memoryview, start: int, header_at: int, at: int, pieces: list[Piece]
    ) -> int:
        """Take a whole header: hold its frame back, or pass it (with the part of it an earlier
        chunk brought); the new start of the bytes in no piece yet."""
        self._left = header.length
        holds = (header.opcode == TEXT and header.fin and not header.rsv1 and not header.mask
                 and not self._in_message and header.length <= self.hold_bytes)  # fmt: skip
        if holds:
            if header_at > start:  # what came before it ends a message: a text frame starts one
                pieces.append(Piece(chunk[start:header_at], True))
            self._held, self._held_header = bytearray(self._header), header.size
            start = at
        elif self._carried:  # the header began in an earlier chunk, before any byte of this one
            pieces.append(Piece(bytes(self._header[: self._carried]), False))
        self._carried = 0
        self._header.clear()
        if header.opcode < 8:  # data: a message ends with its frame that has FIN
            self._in_message = not header.fin
        return start

    def _header_bytes_needed(self) -> int:
        """How many more bytes the header under way may take (at least the next one)."""
        have = len(self._header)
        if have < 2:
            return 2 - have
        length = self._header[1] & 0x7F
        size = (
            2 + (2 if length == 126 else 8 if length == 127 else 0) + (4 if self._header[1] & _MASKED else 0)
        )
        return size - have


def text_frame(text: str, mask: bytes = b"") -> bytes:
    """One unfragmented text frame carrying `text`: a server's (unmasked), or with a 4-byte
    `mask` a client's (its payload masked, as a server requires of every client frame)."""
    payload = text.encode()
    count = len(payload)
    masked = _MASKED if mask else 0
    if count < 126:
        head = bytes([_FIN | TEXT, masked | count])
    elif count < 1 << 16:
        head = bytes([_FIN | TEXT, masked | 126]) + count.to_bytes(2, "big")
    else:
        head = bytes([_FIN | TEXT, masked | 127]) + count.to_bytes(8, "big")
    return head + mask + unmask(payload, mask)
