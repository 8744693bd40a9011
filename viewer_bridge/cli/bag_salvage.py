"""What is readable of a damaged ROS 2 bag, for `convert BAG OUT.lcmlog` (bag_to_lcm.py).

rosbags reads a whole bag or refuses it: an MCAP file cut short (a recording killed mid-chunk)
has no summary nor end magic, and a `.db3` with a damaged page does not open. Both still hold
messages: an MCAP file is read here record by record from its start (mcap's stream reader, CRCs
checked) up to the first record that is cut or damaged, a `.db3` row by row in the order it was
written (Python's sqlite3) up to the first row that cannot be read. The reader gives what rosbags'
does (connections, then `(connection, log time ns, bytes)`) and says in `cut` where it stopped.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["SalvageReader", "cut_reason"]


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


class SalvageReader:
    """The readable part of the MCAP files or `.db3` files of `bag` (a file or a rosbag2 folder).
    `connections` is every topic met before the damage; `messages` yields up to it and then sets
    `cut` (None while nothing is cut)."""

    def __init__(self, bag: Path) -> None:
        self.files = _storage_files(bag)
        self.cut: str | None = None
        self.connections: list[Connection] = []
        for _ in self._read(topics_only=True):
            pass
        self.cut = None  # said again when the messages are read

    def messages(self, connections: list[Any]) -> Iterator[tuple[Any, int, bytes]]:
        wanted = {connection.id for connection in connections}
        for connection, stamp, data in self._read(topics_only=False):
            if connection.id in wanted:
                yield connection, stamp, data

    def close(self) -> None:
        """Nothing stays open between reads."""

    def _read(self, topics_only: bool) -> Iterator[tuple[Connection, int, bytes]]:
        known: dict[tuple[str, str, str], Connection] = {}  # the same topic in several files: one connection
        for path in self.files:
            read = _mcap if path.suffix == ".mcap" else _db3
            try:
                yield from read(path, known, self.connections, topics_only)
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


def _mcap(path: Path, known: dict[tuple[str, str, str], Connection], found: list[Connection],
          topics_only: bool) -> Iterator[tuple[Connection, int, bytes]]:  # fmt: skip
    from mcap.exceptions import EndOfFile
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    schemas: dict[int, Schema] = {}
    channels: dict[int, Connection] = {}
    with path.open("rb") as stream:
        try:
            for record in StreamReader(stream, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel) and record.message_encoding == "cdr" and record.schema_id in schemas:
                    schema = schemas[record.schema_id]
                    text = schema.data.decode("utf-8", "replace") if schema.encoding == "ros2msg" else ""
                    channels[record.id] = _connection(known, found, record.topic, schema.name, text)
                elif isinstance(record, Message) and not topics_only and record.channel_id in channels:
                    yield channels[record.channel_id], record.log_time, record.data
        except EndOfFile:  # mcap says no more than its name
            raise CutShort(f"the file ends inside a record, at byte {path.stat().st_size}: it was cut short") from None


class CutShort(Exception):
    """A storage file that ends before its last record does."""


def _db3(path: Path, known: dict[tuple[str, str, str], Connection], found: list[Connection],
         topics_only: bool) -> Iterator[tuple[Connection, int, bytes]]:  # fmt: skip
    database = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        tables = {row[0] for row in database.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        definitions: dict[str, str] = {}
        if "message_definitions" in tables:  # rosbag2's schema 4 on
            query = "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
            definitions = {name: text for name, encoding, text in database.execute(query) if encoding == "ros2msg"}
        topics = {}
        for topic_id, topic, msgtype, serialization in database.execute(
            "SELECT id, name, type, serialization_format FROM topics"
        ):
            if serialization == "cdr":
                topics[topic_id] = _connection(known, found, topic, msgtype, definitions.get(msgtype, ""))
        if topics_only:
            return
        for topic_id, stamp, data in database.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY id"):
            if topic_id in topics:
                yield topics[topic_id], stamp, data
    finally:
        database.close()
