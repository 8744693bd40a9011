"""WebSocket frames read along a relayed stream, against frames the `websockets` library writes:
any split into chunks, fragments and control frames between them, skipped messages."""

from __future__ import annotations

from hypothesis import example, given, settings
from hypothesis import strategies as st
from websockets.extensions.permessage_deflate import PerMessageDeflate
from websockets.frames import Frame, Opcode

from viewer_bridge.transports.websocket_frames import (
    BINARY,
    TEXT,
    ClientMessages,
    Message,
    MessageEnds,
    text_frame,
)

# A message as (opcode, payload, fragment sizes); a ping may come between its fragments.
messages = st.lists(
    st.tuples(
        st.sampled_from([Opcode.TEXT, Opcode.BINARY]),
        st.binary(max_size=70_000).filter(lambda data: len(data) < 200 or len(data) > 65_000) | st.binary(max_size=300),
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
def test_a_clients_messages_whatever_the_chunks(sent: list[tuple[Opcode, bytes, int, bool]], cuts: list[int]) -> None:
    stream = b"".join(frame.serialize(mask=True) for message in sent for frame in frames_of(*message))
    reader = ClientMessages(max_bytes=1 << 20)
    read = [message for chunk in split(stream, cuts) for message in reader.feed(chunk)]
    assert read == [Message(TEXT if opcode == Opcode.TEXT else BINARY, payload) for opcode, payload, _, _ in sent]


@settings(max_examples=150, deadline=None)
@given(messages, st.lists(st.integers(0, 1 << 20), max_size=12))
def test_the_ends_of_a_servers_messages_whatever_the_chunks(
    sent: list[tuple[Opcode, bytes, int, bool]], cuts: list[int]
) -> None:
    ends: list[int] = []
    stream = b""
    for message in sent:
        stream += b"".join(frame.serialize(mask=False) for frame in frames_of(*message))
        ends.append(len(stream))
    tracker, found, offset = MessageEnds(), list[int](), 0
    for chunk in split(stream, cuts):
        first = tracker.feed(memoryview(chunk))
        if first is not None:
            found.append(offset + first)
        offset += len(chunk)
        # Between two messages exactly when the chunks so far end at a message's end.
        assert tracker.between == (offset in ends or offset == 0), (offset, ends)
    # Each chunk says its first end: every one found is an end, and none is missed where a chunk holds one.
    assert set(found) <= set(ends)
    for chunk_start, chunk in zip(_starts(split(stream, cuts)), split(stream, cuts), strict=True):
        inside = [end for end in ends if chunk_start < end <= chunk_start + len(chunk)]
        if inside:
            assert inside[0] in found


def _starts(chunks: list[bytes]) -> list[int]:
    starts, at = [], 0
    for chunk in chunks:
        starts.append(at)
        at += len(chunk)
    return starts


def test_a_message_too_long_or_compressed_is_skipped_and_said_once() -> None:
    reader = ClientMessages(max_bytes=100)
    long = [Frame(Opcode.BINARY, b"x" * 80, fin=False), Frame(Opcode.CONT, b"y" * 80)]
    deflate = PerMessageDeflate(False, False, 15, 15)  # as a client that negotiated the extension writes
    compressed = Frame(Opcode.TEXT, b'{"op": "advertise", "channels": []}').serialize(mask=True, extensions=[deflate])
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


def _parse(data: bytes) -> Frame:
    """One frame read by `websockets`' own parser (a generator fed the bytes a reader asks for)."""
    from websockets.streams import StreamReader

    stream = StreamReader()
    stream.feed_data(data)
    parser = Frame.parse(stream.read_exact, mask=False)
    try:
        next(parser)
    except StopIteration as done:
        return done.value  # type: ignore[no-any-return]
    raise AssertionError("the frame was not whole")


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
    assert len(reader._buffer) <= 1000 + 14
