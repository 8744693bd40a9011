"""A ROS 2 bag's storage files read directly, for `convert BAG OUT.lcmlog` (bag_to_lcm.py).

An MCAP file is read here record by record from its start (mcap.dev's specification), mapped into
memory: a message is a view into the file, so a byte of an image is copied once, into its LCM
message (rosbags copies it five times: 2-3x slower on an image bag), and the messages come in
the file's order, as they were recorded. A `.db3` is read row by row in the order it was written
(Python's sqlite3). Both read up to the first record or row that is cut or damaged, and say in
`cut` where they stopped: rosbags reads a whole bag or refuses it, and an MCAP file cut short (a
recording killed mid-chunk: no summary, no end magic) or a `.db3` with a damaged page still hold
messages. An MCAP chunk whose records cannot be trusted (it inflates past the size it declares,
does not decompress, fails its CRC) is skipped and said in `damaged`: the file's own record
lengths still frame the records after it. A chunk is inflated at most to the size it declares
(plus one byte, to see that it goes on), so a small file cannot make the reader hold gigabytes;
a summary section is read whole only up to `_SUMMARY_LIMIT` bytes, else the file's records are.
The reader gives what rosbags' does: connections, then `(connection, log time ns, data)`.
"""

from __future__ import annotations

import os
import sqlite3
import struct
import sys
import zlib
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from viewer_bridge.errors import CutShort, DamagedChunk, SummaryTooLarge


@dataclass(frozen=True)
class MessageDefinition:
    data: str  # the `ros2msg` text, as rosbags' `MessageDefinition.data`


@dataclass(frozen=True)
class Connection:
    """A topic as rosbags' `Connection` gives what bag_to_lcm reads of it."""

    id: int
    topic: str
    msgtype: str
    msgdef: MessageDefinition


def cut_reason(error: BaseException) -> str:
    """What a reader's error says, in one line."""
    text = " ".join(str(error).split()) or "no detail"
    return text if isinstance(error, CutShort) else f"{type(error).__name__}: {text}"


class DirectReader:
    """The readable part of the MCAP files or `.db3` files of `bag` (an MCAP file or a rosbag2
    folder). `connections` is every topic met before any damage; `messages` yields up to it and
    then sets `cut` (None while nothing is cut)."""

    def __init__(self, bag: Path) -> None:
        self.files = _storage_files(bag)
        self.cut: str | None = None
        self.damaged: list[str] = []  # the chunks skipped, each `file: the chunk at byte N: why`
        self.unread_summaries: list[str] = []  # MCAP summaries past `_SUMMARY_LIMIT`, each `file: why`
        self.connections: list[Connection] = []
        # the same topic in several files (or found twice): one connection, the same id on every read
        self._known: dict[tuple[str, str, str], Connection] = {}
        # messages per connection id as the files say (an MCAP summary's statistics, a .db3's rows)
        self._counts: Counter[int] | None = Counter()
        counts: Counter[int] | None
        for path in self.files:
            listed, counts = False, Counter[int]()
            if path.suffix == ".mcap":
                try:
                    listed, counts = _summary_connections(path, self._known, self.connections)
                except SummaryTooLarge as error:  # an index too large to hold: the records say the same
                    self.unread_summaries.append(str(error))
                    counts = None
            if not listed:  # its records are read for its channels (a .db3's rows counted meanwhile)
                for _ in self._read([path], None, counts):
                    pass
            if self._counts is None or counts is None or _UNCOUNTED in counts:
                self._counts = None  # a file that does not say: no total
            else:
                self._counts += counts
            if self.cut is not None:
                self._counts = None
                break
        self.cut = None  # said again when the messages are read
        self.damaged_chunks = len(self.damaged)  # found while reading the topics
        self.damaged = []

    def message_count(self, connections: list[Any]) -> int | None:
        """How many messages the bag holds on `connections`, when every file says (without reading
        its messages); None when one does not (an MCAP file cut short, or without statistics)."""
        if self._counts is None:
            return None
        return sum(self._counts[connection.id] for connection in connections)

    def messages(self, connections: list[Any]) -> Iterator[tuple[Any, int, bytes | memoryview]]:
        return self._read(self.files, {connection.id for connection in connections})

    def close(self) -> None:
        """Nothing stays open between reads."""

    def _read(
        self, files: list[Path], wanted: set[int] | None, counts: Counter[int] | None = None
    ) -> Iterator[tuple[Connection, int, bytes | memoryview]]:
        """The messages of the connections `wanted` (None: none, the connections are found; a
        `.db3`'s rows are counted per connection into `counts`)."""
        for path in files:
            try:
                if path.suffix == ".db3":
                    yield from _db3(path, self._known, self.connections, wanted, counts)
                else:
                    yield from _mcap(path, self._known, self.connections, wanted, self.damaged)
            except Exception as error:  # noqa: BLE001 - whatever the damage, the rest of the bag is unreadable
                self.cut = f"{path.name}: {cut_reason(error)}"
                return


def _storage_files(bag: Path) -> list[Path]:
    """The storage files of a bag: itself, or a rosbag2 folder's `.mcap`/`.db3` files in their
    order (`bag_0`, `bag_1`, ..., `bag_10`: by the number that ends the name)."""
    if bag.is_file():
        return [bag]

    def order(path: Path) -> tuple[int, str]:
        digits = path.stem.rsplit("_", 1)[-1]
        return (int(digits) if digits.isdigit() else -1, path.name)

    return sorted((p for p in bag.iterdir() if p.suffix in (".mcap", ".db3")), key=order)


def _connection(known: dict[tuple[str, str, str], Connection], found: list[Connection], topic: str, msgtype: str,
                definition: str) -> Connection:  # fmt: skip
    key = (topic, msgtype, definition)
    if key not in known:
        known[key] = Connection(len(known), topic, msgtype, MessageDefinition(definition))
        found.append(known[key])
    return known[key]


def _summary_connections(
    path: Path, known: dict[tuple[str, str, str], Connection], found: list[Connection]
) -> tuple[bool, Counter[int] | None]:
    """The connections of an MCAP file read from its summary section (where a finished file
    repeats its schemas and channels), without inflating a chunk; False when the file has no
    footer, no summary or no channel in it (cut short, or written without): then its records are
    read. Whatever the summary says, the messages are still read from the data section. With it,
    the messages per connection id its Statistics record counts (None without one).
    `SummaryTooLarge` when the footer puts more than `_SUMMARY_LIMIT` bytes in the summary: read
    whole, a made-up footer would have the reader hold the file."""
    with path.open("rb") as stream:
        size = os.fstat(stream.fileno()).st_size
        footer_at = size - len(_MAGIC) - _RECORD.size - _FOOTER.size
        if footer_at < len(_MAGIC):
            return False, None
        stream.seek(footer_at)
        tail = stream.read()
        if tail[-len(_MAGIC) :] != _MAGIC or _RECORD.unpack_from(tail) != (_OP_FOOTER, _FOOTER.size):
            return False, None
        summary_start, offsets_start, _ = _FOOTER.unpack_from(tail, _RECORD.size)
        summary_end = offsets_start or footer_at
        if not len(_MAGIC) <= summary_start < summary_end <= footer_at:
            return False, None
        if summary_end - summary_start > _SUMMARY_LIMIT:
            raise SummaryTooLarge(
                f"{path.name}: its summary section of {summary_end - summary_start} bytes (from byte "
                f"{summary_start}) is past the {_SUMMARY_LIMIT >> 20} MiB read whole: its records are read instead"
            )
        stream.seek(summary_start)
        records = memoryview(stream.read(summary_end - summary_start))
    try:
        channels, statistics = _summary(records, known, found)
        return bool(channels), None if statistics is None else _statistics(statistics, channels)
    except (struct.error, ValueError):
        return False, None


def _summary(records: memoryview, known: dict[tuple[str, str, str], Connection],
             found: list[Connection]) -> tuple[dict[int, Connection], memoryview | None]:  # fmt: skip
    """A summary's channels (by channel id) and its Statistics record (None without one), in one
    walk over its records; ValueError when a record runs past the summary's end."""
    schemas: dict[int, tuple[str, str]] = {}
    channels: dict[int, Connection] = {}
    statistics = None
    at = 0
    while at < len(records):
        op, length = _RECORD.unpack_from(records, at)
        start, at = at + _RECORD.size, at + _RECORD.size + length
        if at > len(records):
            raise ValueError(f"its record of {length} bytes runs past its end")
        if op == _OP_STATISTICS:
            statistics = records[start:at]  # read once the channels are known: it may come first
        else:
            _definition(op, records[start:at], schemas, channels, known, found)
    return channels, statistics


def _statistics(record: memoryview, channels: dict[int, Connection]) -> Counter[int] | None:
    """The messages per connection id a Statistics `record` counts (its `channel_message_counts`:
    a uint32 byte length, then uint16 channel id, uint64 count pairs); None when it counts
    messages but not per channel (the map is optional)."""
    (messages,) = _U64.unpack_from(record)
    pairs = _sized(record, _STATISTICS.size, 4)
    if messages and not pairs:
        return None
    counts: Counter[int] = Counter()
    for pair in range(0, len(pairs) - _COUNT.size + 1, _COUNT.size):
        channel_id, count = _COUNT.unpack_from(pairs, pair)
        if channel_id in channels:
            counts[channels[channel_id].id] += count
    return counts


def _mcap(path: Path, known: dict[tuple[str, str, str], Connection], found: list[Connection],
          wanted: set[int] | None, damaged: list[str]) -> Iterator[tuple[Connection, int, bytes | memoryview]]:  # fmt: skip
    """An MCAP file's messages in the file's order, each a view into the record read from the file:
    a byte of an image is copied from the file once, and once more into its LCM message. The MCAP
    records (mcap.dev's specification): opcode, uint64 length, content, all little-endian. A
    damaged chunk is skipped from where its damage is found, and said in `damaged`."""
    schemas: dict[int, tuple[str, str]] = {}  # id -> (name, ros2msg text)
    channels: dict[int, Connection] = {}
    with path.open("rb") as stream:
        if stream.read(len(_MAGIC)) != _MAGIC:
            raise ValueError("it does not start with MCAP's magic bytes")
        for op, at, record in _file_records(stream, os.fstat(stream.fileno()).st_size):
            if op == _OP_CHUNK:
                try:
                    yield from _chunk_messages(
                        _chunk_records(record), schemas, channels, known, found, wanted
                    )
                except DamagedChunk as error:
                    damaged.append(f"{path.name}: the chunk at byte {at}: {error}")
            elif op == _OP_MESSAGE:
                message = _message(record, 0, len(record), channels, wanted)
                if message is not None:
                    yield message
            elif op == _OP_DATA_END:
                return
            else:
                _definition(op, record, schemas, channels, known, found)


def _chunk_messages(records: memoryview, schemas: dict[int, tuple[str, str]], channels: dict[int, Connection],
                    known: dict[tuple[str, str, str], Connection], found: list[Connection],
                    wanted: set[int] | None) -> Iterator[tuple[Connection, int, memoryview]]:  # fmt: skip
    """The messages among a chunk's records, each a view into them; schemas and channels remembered."""
    at, end = 0, len(records)
    while at < end:  # a loop here, not a generator of records: a chunk may hold thousands of messages
        if at + _RECORD.size > end:
            raise DamagedChunk(f"it ends inside a record's opcode and length, at its byte {at}")
        op, length = _RECORD.unpack_from(records, at)
        start, at = at + _RECORD.size, at + _RECORD.size + length
        if at > end:
            raise DamagedChunk(f"its record of {length} bytes runs past its end")
        if op != _OP_MESSAGE:
            _definition(op, records[start:at], schemas, channels, known, found)
            continue
        message = _message(records, start, at, channels, wanted)
        if message is not None:
            yield message


def _message(records: memoryview, start: int, stop: int, channels: dict[int, Connection],
             wanted: set[int] | None) -> tuple[Connection, int, memoryview] | None:  # fmt: skip
    """The message record at `start` as (connection, log time, its data), if its channel is wanted."""
    if not wanted or stop - start < _MESSAGE.size:
        return None
    channel_id, _, log_time, _ = _MESSAGE.unpack_from(records, start)
    connection = channels.get(channel_id)
    if connection is None or connection.id not in wanted:
        return None
    return connection, log_time, records[start + _MESSAGE.size : stop]


def _file_records(stream: Any, size: int) -> Iterator[tuple[int, int, memoryview]]:
    """The records of an MCAP file from where `stream` is, each read whole with where it starts (a
    length past the file's end is refused before anything is read: no allocation for a made-up
    length)."""
    while True:
        head = stream.read(_RECORD.size)
        if not head:
            return
        at = stream.tell() - len(head)
        if len(head) < _RECORD.size:
            raise CutShort(f"the file ends inside a record, at byte {size}: it was cut short")
        op, length = _RECORD.unpack(head)
        if length > size - at - _RECORD.size:
            raise CutShort(f"the file ends inside a record of {length} bytes at byte {at}: it was cut short")
        yield op, at, memoryview(stream.read(length))


def _definition(op: int, record: memoryview, schemas: dict[int, tuple[str, str]], channels: dict[int, Connection],
                known: dict[tuple[str, str, str], Connection], found: list[Connection]) -> None:  # fmt: skip
    """A schema or channel record, remembered; any other record but a message means nothing here."""
    if op == _OP_SCHEMA:
        (schema_id,) = _U16.unpack_from(record)
        name, at = _string(record, 2)
        encoding, at = _string(record, at)
        text = bytes(_sized(record, at, 4)).decode("utf-8", "replace") if encoding == "ros2msg" else ""
        schemas[schema_id] = (name, text)
    elif op == _OP_CHANNEL:
        channel_id, schema_id = _U16_U16.unpack_from(record)
        topic, at = _string(record, 4)
        encoding, _ = _string(record, at)
        if encoding == "cdr" and schema_id in schemas:
            channels[channel_id] = _connection(known, found, topic, *schemas[schema_id])


_MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_DATA_END = 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F
_OP_STATISTICS = 0x0B
_RECORD = struct.Struct("<BQ")
_FOOTER = struct.Struct("<QQI")  # summary start, summary offsets start, summary CRC-32
_MESSAGE = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time; then the data
# Statistics: message, schema, channel, attachment, metadata and chunk counts, first and last message
# times; then the messages per channel
_STATISTICS = struct.Struct("<QHIIIIQQ")
_COUNT = struct.Struct("<HQ")  # a channel id, its messages
_UNCOUNTED = -1  # no connection's id: in a file's counts, the file could not count its messages
_CHUNK = struct.Struct("<QQQI")  # start time, end time, uncompressed size, uncompressed CRC-32 (0: none)
_U16, _U16_U16, _U32, _U64 = (
    struct.Struct("<H"),
    struct.Struct("<HH"),
    struct.Struct("<I"),
    struct.Struct("<Q"),
)


def _chunk_records(chunk: memoryview) -> memoryview:
    """A chunk's records, decompressed (never past the size it declares) and checked against its
    size and CRC; `DamagedChunk` says why they cannot be."""
    try:
        _, _, size, crc = _CHUNK.unpack_from(chunk)
        compression, at = _string(chunk, _CHUNK.size)
        records = _sized(chunk, at, 8)
    except (struct.error, ValueError) as error:
        raise DamagedChunk(f"its header is damaged: {error}") from None
    if compression:
        records = memoryview(_inflated(compression, records, size))
    if len(records) != size:
        raise DamagedChunk(f"it holds {len(records)} bytes where it declares {size}")
    if crc and zlib.crc32(records) != crc:
        raise DamagedChunk("its CRC-32 does not match its records")
    return records


def _inflated(compression: str, data: memoryview, size: int) -> bytes:
    """`data` decompressed as `compression` (`zstd` or `lz4`: one frame or several in a row),
    stopped one byte past `size`: a chunk that declares 100 bytes and would inflate to gigabytes
    costs 101 bytes here, and is `DamagedChunk`. Asked for at most `_INFLATE_STEP` bytes a call
    (lz4 allocates what it is allowed before it reads: a made-up size would be allocated whole)."""
    new, errors = _decompressor(compression)
    pieces: list[bytes] = []
    total, rest = 0, bytes(data)
    try:
        while True:  # a frame
            decompressor = new()
            while True:
                piece = decompressor.decompress(rest, max_length=min(size + 1 - total, _INFLATE_STEP))
                rest = b""  # kept by the decompressor until it is used
                total += len(piece)
                pieces.append(piece)
                if total > size:
                    raise DamagedChunk(f"it inflates past the {size} bytes it declares")
                if decompressor.eof or decompressor.needs_input or not piece:  # not piece: stuck
                    break
            if not decompressor.eof:
                raise DamagedChunk(f"its {compression} data ends inside a frame")
            rest = decompressor.unused_data
            if not rest:
                return b"".join(pieces)  # one piece: that piece, not copied
    except errors as error:
        raise DamagedChunk(f"its {compression} data does not decompress: {error}") from None


_INFLATE_STEP = 1 << 20
# The most of an MCAP summary read into memory: a 100 GB recording of 50 topics in 1 MiB chunks
# indexes them in at most about 55 MB; past it, the file's records give its topics (no total).
_SUMMARY_LIMIT = 64 << 20


def _decompressor(compression: str) -> tuple[Any, tuple[type[Exception], ...]]:
    """A `compression`'s streaming decompressor class (each call one frame) and the errors it
    raises on bad data."""
    if compression == "zstd":
        if sys.version_info >= (3, 14):
            from compression import zstd
        else:
            from backports import zstd  # rosbags' dependency
        return zstd.ZstdDecompressor, (zstd.ZstdError, EOFError)
    if compression == "lz4":
        from lz4.frame import LZ4FrameDecompressor  # type: ignore[import-untyped]  # rosbags' dependency

        return LZ4FrameDecompressor, (RuntimeError, EOFError)
    raise DamagedChunk(f"it is compressed as {compression!r}, which this reader does not know")


def _sized(record: memoryview, at: int, width: int) -> memoryview:
    """The bytes after a uint32 (`width` 4) or uint64 (8) length at `at`."""
    (length,) = (_U32 if width == 4 else _U64).unpack_from(record, at)
    if at + width + length > len(record):
        raise ValueError(f"a field of {length} bytes runs past its record")
    return record[at + width : at + width + length]


def _string(record: memoryview, at: int) -> tuple[str, int]:
    """The uint32-prefixed UTF-8 string at `at`, and where it ends."""
    data = _sized(record, at, 4)
    return str(data, "utf-8", "replace"), at + 4 + len(data)


def _db3(path: Path, known: dict[tuple[str, str, str], Connection], found: list[Connection],
         wanted: set[int] | None,
         counts: Counter[int] | None = None) -> Iterator[tuple[Connection, int, bytes | memoryview]]:  # fmt: skip
    database = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        tables = {row[0] for row in database.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        definitions: dict[str, str] = {}
        if "message_definitions" in tables:  # rosbag2's schema 4 on
            query = "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
            definitions = {
                name: text for name, encoding, text in database.execute(query) if encoding == "ros2msg"
            }
        topics = {}
        for topic_id, topic, msgtype, serialization in database.execute(
            "SELECT id, name, type, serialization_format FROM topics"
        ):
            if serialization == "cdr":
                topics[topic_id] = _connection(known, found, topic, msgtype, definitions.get(msgtype, ""))
        if counts is not None:  # the rows per topic, for the progress' total (sqlite reads no blob for it)
            try:
                query = "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id"
                for topic_id, rows in database.execute(query).fetchall():
                    if topic_id in topics:
                        counts[topics[topic_id].id] += rows
            except sqlite3.DatabaseError:  # a damaged page: said when the messages are read; no total
                counts[_UNCOUNTED] = 1
        if not wanted:
            return
        for topic_id, stamp, data in database.execute(
            "SELECT topic_id, timestamp, data FROM messages ORDER BY id"
        ):
            connection = topics.get(topic_id)
            if connection is not None and connection.id in wanted:
                yield connection, stamp, data
    finally:
        database.close()
