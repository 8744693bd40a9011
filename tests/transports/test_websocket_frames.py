"""WebSocket frames read along a relayed stream, against frames the `websockets` library writes
and reads: any split into chunks, fragments and control frames between them, skipped messages,
text messages held back whole and dropped."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from websockets.extensions.permessage_deflate import PerMessageDeflate
from websockets.frames import Frame, Opcode

from viewer_bridge.errors import FrameLimitError
from viewer_bridge.transports.websocket_frames import (
    BINARY,
    MAX_FRAGMENTS,
    TEXT,
    ClientMessages,
    Message,
    RelayedStream,
    text_frame,
)

# A message as (opcode, payload, fragment sizes); a ping may come between its fragments.
messages = st.lists(
    st.tuples(
        st.sampled_from([Opcode.TEXT, Opcode.BINARY]),
        st.binary(max_size=70_000).filter(lambda data: len(data) < 200 or len(data) > 65_000)
        | st.binary(max_size=300),
        st.integers(1, 4),
        st.booleans(),
    ),
    min_size=1,
    max_size=6,
)


def frames_of(opcode: Opcode, payload: bytes, parts: int, ping: bool) -> list[Frame]:
    """The message as `parts` frames (the first with its opcode, then continuations), a ping
    after the first when `ping` and there are several."""
    size = -(-len(payload) // parts) or 1
    pieces = [payload[at : at + size] for at in range(0, len(payload), size)] or [b""]
    frames = [Frame(opcode if index == 0 else Opcode.CONT, piece, fin=index == len(pieces) - 1)
              for index, piece in enumerate(pieces)]  # fmt: skip
    if ping and len(frames) > 1:  # between fragments: no message ends there
        frames.insert(1, Frame(Opcode.PING, b"are you there"))
    return frames


def split(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({cut % (len(data) + 1) for cut in cuts})
    return [data[start:end] for start, end in zip([0, *points], [*points, len(data)], strict=True)]


@settings(max_examples=150, deadline=None)
@given(messages, st.lists(st.integers(0, 1 << 20), max_size=12))
def test_a_clients_messages_whatever_the_chunks(
    sent: list[tuple[Opcode, bytes, int, bool]], cuts: list[int]
) -> None:
    stream = b"".join(frame.serialize(mask=True) for message in sent for frame in frames_of(*message))
    reader = ClientMessages(max_bytes=1 << 20)
    read = [message for chunk in split(stream, cuts) for message in reader.feed(chunk)]
    assert read == [
        Message(TEXT if opcode == Opcode.TEXT else BINARY, payload) for opcode, payload, _, _ in sent
    ]


HOLD = 300  # text messages up to this size are held back whole in these tests


def server_stream(sent: list[tuple[Opcode, bytes, int, bool]]) -> tuple[bytes, list[int], list[bytes]]:
    """The messages as a server's frames: the stream, where each message ends, and the payloads
    of the text messages a reader holding HOLD bytes holds back (unfragmented, short)."""
    stream, ends, held = b"", [], []
    for message in sent:
        frames = frames_of(*message)
        stream += b"".join(frame.serialize(mask=False) for frame in frames)
        ends.append(len(stream))
        opcode, payload, _, _ = message
        if opcode == Opcode.TEXT and len(frames) == 1 and len(payload) <= HOLD:
            held.append(payload)
    return stream, ends, held


@settings(max_examples=150, deadline=None)
@given(messages, st.lists(st.integers(0, 1 << 20), max_size=12), st.booleans())
def test_a_relayed_stream_passes_every_byte_in_order_cut_where_messages_end(
    sent: list[tuple[Opcode, bytes, int, bool]], cuts: list[int], cut_first_end: bool
) -> None:
    stream, ends, held = server_stream(sent)
    reader, passed, texts, boundaries, offset = RelayedStream(HOLD), bytearray(), list[bytes](), set[int](), 0
    for chunk in split(stream, cuts):
        for piece in reader.feed(memoryview(chunk), cut_first_end):
            passed += piece.data
            # A piece says whether the stream's bytes up to it end with a whole message.
            assert piece.ends_message == (len(passed) in ends), (len(passed), ends)
            if piece.ends_message:
                boundaries.add(len(passed))
            if piece.text is not None:  # a whole text frame, read as the library reads it
                frame = _parse(bytes(piece.data))
                assert frame.opcode == Opcode.TEXT and frame.fin and frame.data == piece.text
                texts.append(piece.text)
        # Between two messages exactly when what has passed ends at a message's end (or is nothing).
        assert reader.between == (len(passed) in ends or not passed), (len(passed), ends)
        offset += len(chunk)
        inside = [end for end in ends if offset - len(chunk) < end <= offset]
        if cut_first_end and inside:  # asked to, it cuts where the chunk's first message ends
            assert inside[0] in boundaries
    assert bytes(passed) == stream
    assert texts == held


@settings(max_examples=100, deadline=None)
@given(messages, st.lists(st.integers(0, 1 << 20), max_size=12))
def test_dropping_held_text_messages_leaves_a_stream_the_library_reads(
    sent: list[tuple[Opcode, bytes, int, bool]], cuts: list[int]
) -> None:
    stream, _, held = server_stream(sent)
    reader, kept = RelayedStream(HOLD), bytearray()
    for chunk in split(stream, cuts):
        for piece in reader.feed(memoryview(chunk), cut_first_end=True):
            if piece.text is None:
                kept += piece.data
    others = [payload for opcode, payload, parts, _ in sent if not (
        opcode == Opcode.TEXT and len(frames_of(opcode, payload, parts, False)) == 1 and len(payload) <= HOLD)]  # fmt: skip
    assert [frame.data for frame in _messages(bytes(kept))] == others
    assert len(held) + len(others) == len(sent)


def test_what_a_relayed_stream_does_not_hold() -> None:
    deflate = PerMessageDeflate(False, False, 15, 15)  # a server that negotiated it: RSV1 set
    frames = [
        Frame(Opcode.TEXT, b'{"op": "status"}').serialize(mask=False, extensions=[deflate]),  # compressed
        Frame(Opcode.TEXT, b"x" * (HOLD + 1)).serialize(mask=False),  # too long
        Frame(Opcode.TEXT, b"part", fin=False).serialize(mask=False)
        + Frame(Opcode.CONT, b"s").serialize(mask=False),
        Frame(Opcode.TEXT, b"masked").serialize(mask=True),  # no server's
        Frame(Opcode.TEXT, b"").serialize(mask=False),  # held: an empty text message is one
    ]
    pieces = RelayedStream(HOLD).feed(memoryview(b"".join(frames)))
    assert [piece.text for piece in pieces if piece.text is not None] == [b""]
    assert b"".join(bytes(piece.data) for piece in pieces) == b"".join(frames)


def test_a_header_cut_by_a_chunks_end_is_held_back_until_whole() -> None:
    binary = Frame(Opcode.BINARY, b"b" * 70_000).serialize(mask=False)  # a 10-byte header
    status = Frame(Opcode.TEXT, b'{"op": "status"}').serialize(mask=False)
    reader = RelayedStream(HOLD)
    first = reader.feed(memoryview(binary[:5]))
    assert first == []  # half a header: nothing passes yet
    rest = reader.feed(memoryview(binary[5:] + status[:1]))
    assert [bytes(piece.data) for piece in first + rest] == [binary[:5], binary[5:]]
    assert rest[-1].ends_message and reader.between
    (held,) = reader.feed(memoryview(status[1:]))
    assert held.text == b'{"op": "status"}' and bytes(held.data) == status


def _messages(data: bytes) -> list[Frame]:
    """The data messages in `data` (server frames), fragments joined, control frames left out."""
    from websockets.streams import StreamReader

    stream = StreamReader()
    stream.feed_data(data)
    messages: list[Frame] = []
    while stream.buffer:
        frame = _run(Frame.parse(stream.read_exact, mask=False))
        if frame.opcode == Opcode.CONT:
            messages[-1] = Frame(messages[-1].opcode, messages[-1].data + frame.data)
        elif frame.opcode in (Opcode.TEXT, Opcode.BINARY):
            messages.append(frame)
    return messages


def _run(parser: Any) -> Frame:
    try:
        next(parser)
    except StopIteration as done:
        return done.value  # type: ignore[no-any-return]
    raise AssertionError("the frame was not whole")


def test_a_clients_text_messages_alone() -> None:
    reader = ClientMessages(max_bytes=100, binary=False)
    stream = b"".join(frame.serialize(mask=True) for frame in [
        Frame(Opcode.BINARY, b"x" * 80, fin=False), Frame(Opcode.PING, b""), Frame(Opcode.CONT, b"y" * 80),
        Frame(Opcode.TEXT, b'{"op": "subscribe"}')])  # fmt: skip
    read = [message for chunk in split(stream, [3, 50, 120]) for message in reader.feed(chunk)]
    assert read == [Message(TEXT, b'{"op": "subscribe"}')]  # the binary one not even as skipped


def test_a_message_too_long_or_compressed_is_skipped_and_said_once() -> None:
    reader = ClientMessages(max_bytes=100)
    long = [Frame(Opcode.BINARY, b"x" * 80, fin=False), Frame(Opcode.CONT, b"y" * 80)]
    deflate = PerMessageDeflate(False, False, 15, 15)  # as a client that negotiated the extension writes
    compressed = Frame(Opcode.TEXT, b'{"op": "advertise", "channels": []}').serialize(
        mask=True, extensions=[deflate]
    )
    after = Frame(Opcode.TEXT, b'{"op": "advertise"}')
    stream = b"".join(frame.serialize(mask=True) for frame in long) + compressed + after.serialize(mask=True)
    read = [message for chunk in split(stream, [7, 90, 150, 170]) for message in reader.feed(chunk)]
    assert [(message.opcode, message.skipped) for message in read] == [
        (BINARY, "longer than 100 bytes"),
        (TEXT, "compressed (an extension the bridge does not read)"),
        (TEXT, None),
    ]
    assert read[-1].payload == b'{"op": "advertise"}'


def test_a_text_frame_of_the_relays_own_reads_as_the_library_reads_it() -> None:
    for size in (0, 125, 126, 65_535, 65_536):
        text = "é" * (size // 2) + "a" * (size % 2)
        frame = _parse(text_frame(text))
        assert frame.opcode == Opcode.TEXT and frame.fin and frame.data.decode() == text
        # A client's, masked: a server's parser requires the mask and unmasks it.
        frame = _parse(text_frame(text, mask=b"\x01\x80\xfe\x37"), mask=True)
        assert frame.opcode == Opcode.TEXT and frame.fin and frame.data.decode() == text


def _parse(data: bytes, mask: bool = False) -> Frame:
    """One frame read by `websockets`' own parser (a generator fed the bytes a reader asks for),
    as a client reads a server's (`mask` false) or a server a client's."""
    from websockets.streams import StreamReader

    stream = StreamReader()
    stream.feed_data(data)
    return _run(Frame.parse(stream.read_exact, mask=mask))


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=2000), st.lists(st.integers(0, 1 << 20), max_size=8))
@example(bytes([0x83, 0x82, 0, 0, 0, 0, 65, 66]), [])  # a reserved opcode
@example(bytes([0x89, 0xFF]) + b"\xff" * 12, [5])  # a ping claiming 2**64 - 1 bytes
def test_any_bytes_from_a_client_are_read_without_an_error_and_kept_within_bounds(
    junk: bytes, cuts: list[int]
) -> None:
    reader = ClientMessages(max_bytes=1000)
    for chunk in split(junk, cuts):
        for message in reader.feed(chunk):
            assert message.opcode in (TEXT, BINARY) or message.skipped is not None
            assert len(message.payload) <= 1000
    # What it holds is at most a partial header or a frame within the limit, never a claimed length.
    assert reader.held_bytes <= 1000 + 14


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=2000), st.lists(st.integers(0, 1 << 20), max_size=8))
@example(bytes([0x81, 0x7F]) + b"\xff" * 8 + b"x", [3])  # a text frame claiming 2**64 - 1 bytes
def test_any_bytes_from_a_server_pass_in_order_and_what_is_held_stays_bounded(
    junk: bytes, cuts: list[int]
) -> None:
    reader, passed = RelayedStream(HOLD), bytearray()
    for chunk in split(junk, cuts):
        for piece in reader.feed(memoryview(chunk)):
            passed += piece.data
            assert piece.text is None or len(piece.text) <= HOLD
        assert reader.held_bytes <= HOLD + 14  # at most a frame it holds, or a header cut short
    assert junk.startswith(bytes(passed)) and len(junk) - len(passed) <= HOLD + 14


def _fragmented(first: bytes, continuations: list[bytes]) -> bytes:
    """A text message as a client sends it: `first`, then each continuation (the last with FIN)."""
    frames = [Frame(Opcode.TEXT, first, fin=not continuations)]
    frames += [
        Frame(Opcode.CONT, part, fin=index == len(continuations) - 1)
        for index, part in enumerate(continuations)
    ]
    return b"".join(frame.serialize(mask=True) for frame in frames)


def test_a_message_in_more_fragments_than_a_client_sends_ends_the_stream_whatever_their_size() -> None:
    """3M one-byte continuation frames cost the original reader 167 MiB and half a minute of
    CPU; the reader now gives up at MAX_FRAGMENTS frames (its client is let go)."""
    reader = ClientMessages(max_bytes=1 << 24)
    assert reader.feed(_fragmented(b"x", [b"y"] * (MAX_FRAGMENTS - 1))) == [Message(TEXT, b"x" + b"y" * 1023)]
    with pytest.raises(FrameLimitError, match=f"more than {MAX_FRAGMENTS} frames"):
        reader.feed(_fragmented(b"x", [b""] * MAX_FRAGMENTS))


def test_empty_continuation_frames_count_toward_a_messages_size() -> None:
    """Each continuation frame costs its header: 200 empty ones (6 bytes each, masked) are more
    than a 1 kB limit, though they carry no byte."""
    reader = ClientMessages(max_bytes=1024, limit_name="foxglove.max_client_message_bytes")
    (skipped,) = reader.feed(_fragmented(b"0123456789", [b""] * 200))
    assert (
        skipped.payload == b""
        and skipped.skipped == "longer than 1024 bytes (foxglove.max_client_message_bytes)"
    )
    assert reader.feed(_fragmented(b"fine", [b""] * 10)) == [Message(TEXT, b"fine")]
