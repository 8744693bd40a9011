"""A ROS 2 bag (an MCAP file, or a rosbag2 folder of .db3 or .mcap storage) -> an LCM log.

Every topic of a type that maps onto LCM (docs/PROTOCOLS.md section 14) becomes a channel, its
name the topic without the leading `/` (`/joint_states` -> `joint_states`, `/arm/state` ->
`arm/state`); each message is converted by the compiled CDR -> LCM code and written with its log
time (in microseconds, LCM's unit) as the event's timestamp, in the bag's order. The types come
from the bag's own `ros2msg` definitions where it has them, else from the Jazzy store. A message
that does not convert is counted per topic, not written, and the conversion goes on.
"""

from __future__ import annotations

import re
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from viewer_bridge.cli.bag_files import DirectReader, cut_reason
from viewer_bridge.errors import ConvertError, DecodeError, Interrupted
from viewer_bridge.lcmcodec.from_ros import LcmFromRos, definitions_from_msgdef, lcm_channel, map_ros_types
from viewer_bridge.lcmcodec.ros_cdr import compile_ros_encoders
from viewer_bridge.transports.lcm import LcmEvent, write_log
from viewer_bridge.util.partial import check_output_folder, partial_output
from viewer_bridge.util.progress import progress as progress_of

__all__ = ["BagConversion", "bag_to_lcm", "is_ros_bag"]

# Messages up to this size are handed over as bytes (the encoders' kept layouts read bytes); a larger
# one is read where the reader has it (a view into the file), and copied once, into its LCM message.
_COPY_UP_TO = 16384


@dataclass
class BagConversion:
    """What a conversion did: messages written and refused per topic, and the topics left out."""

    written: Counter[str] = field(default_factory=Counter)  # by topic
    bad: Counter[str] = field(default_factory=Counter)  # by topic: messages that did not convert
    first_error: dict[str, str] = field(default_factory=dict)  # by topic
    skipped: dict[str, str] = field(default_factory=dict)  # topic -> why it has no channel
    channels: dict[str, str] = field(default_factory=dict)  # topic -> LCM channel
    lcm_files: list[Path] = field(default_factory=list)
    # by topic: rows whose stored values are no message
    damaged: Counter[str] = field(default_factory=Counter)
    first_damage: dict[str, str] = field(default_factory=dict)  # by topic
    cut: str | None = None  # where the bag's readable part ends, when it ends before the bag does
    damaged_chunks: list[str] = field(default_factory=list)  # MCAP chunks skipped, each with why
    # MCAP summaries too large to read whole, each with why: their files' records were read instead
    unread_summaries: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        """Whether every message the bag stores was read (converted, or refused as a bad message)."""
        return self.cut is None and not self.damaged and not self.damaged_chunks


def is_ros_bag(path: str | Path) -> bool:
    """A rosbag2 folder or an MCAP file (by its magic bytes), as opposed to an LCM log."""
    path = Path(path)
    if path.is_dir():
        return True
    with path.open("rb") as file:
        return file.read(5) == b"\x89MCAP"


def bag_to_lcm(bag: str | Path, out: str | Path, *, topics: str | None = None, lcm_types_out: str | Path | None = None,
               force: bool = False, stop: threading.Event | None = None,
               progress: bool = False) -> BagConversion:  # fmt: skip
    """Convert the topics of `bag` (those whose name fully matches the regex `topics`, default all)
    into the LCM log `out`; write the `.lcm` files of their types under `lcm_types_out` if given.
    Raises `ConvertError` before writing anything when `out` exists (unless `force`) or is a
    folder, `lcm_types_out` cannot be a folder, or no topic maps. The log is written as
    `out.partial` and renamed once complete (`util/partial.py`); `stop` set midway (Ctrl-C) ends
    it there, keeps `out.partial` (a readable log; none when no message was written yet) and
    raises `Interrupted`. `progress`: shown on stderr (`util/progress.py`), of the total the bag
    says it holds on the topics chosen, when it says.
    A damaged bag is converted as far as it can be read: `result.cut` and `result.damaged` say what was not."""
    target = Path(out)
    if target.is_dir():
        raise ConvertError(f"{target} is a folder, not a file")
    if target.exists() and not force:
        raise ConvertError(f"{target} exists (--force replaces it)")
    if lcm_types_out is not None:
        check_output_folder(Path(lcm_types_out), "--lcm-types-out")
    stop = stop or threading.Event()
    result = BagConversion()
    pattern = re.compile(topics) if topics is not None else None
    reader = _open(Path(bag))
    try:
        connections = [c for c in reader.connections if pattern is None or pattern.fullmatch(c.topic)]
        definitions, unreadable = _definitions(connections)
        mapping = map_ros_types(definitions, [c.msgtype for c in connections if c.msgtype not in unreadable])
        chosen = _channels(connections, {**mapping.refused, **unreadable}, result)
        if not chosen:
            reasons = (
                "; ".join(f"{topic}: {why}" for topic, why in result.skipped.items()) or "no topic matches"
            )
            raise ConvertError(f"no topic of {bag} maps onto LCM: {reasons}")
        encoders = compile_ros_encoders(mapping, dict.fromkeys(c.msgtype for c in chosen))
        by_id = {c.id: (c.topic, result.channels[c.topic], encoders[c.msgtype]) for c in chosen}
        shown = progress_of("viewer-bridge convert", "converting", *_progress_total(reader, chosen))
        with partial_output(target) as partial, shown if progress else nullcontext(_no_progress) as advance:
            events = _events(_readable(reader, chosen, result), by_id, result, stop, advance)
            write_log(partial, events)
            if stop.is_set():
                raise Interrupted(sum(result.written.values()), partial)
            if result.cut is not None:
                read = sum(result.written.values()) + sum(result.bad.values()) + sum(result.damaged.values())
                result.cut += f"; the {read} messages before it are converted, the rest is lost"
            if lcm_types_out is not None:  # the types of the topics written, and what they nest
                keep = {
                    mapping.structs[name].lcm_name for name in _nested(mapping, {c.msgtype for c in chosen})
                }
                mapping.texts = {name: text for name, text in mapping.texts.items() if name in keep}
                result.lcm_files = mapping.write(Path(lcm_types_out))
    finally:
        reader.close()
    return result


def _open(bag: Path) -> Any:
    """The reader of `bag`, an MCAP file or a rosbag2 folder: the project's own (`bag_files`: in
    place, and as far as it is readable) for MCAP and `.db3` storage alike. rosbags' opens only
    what that cannot: a folder whose storage files rosbag2 compressed whole (`bag_0.mcap.zstd`)."""
    direct = DirectReader(bag)
    if direct.connections:
        return direct
    if direct.files or bag.is_file():
        raise ConvertError(f"{bag} holds no CDR topic that can be read: {direct.cut or 'none is recorded'}")
    from rosbags.rosbag2 import Reader, ReaderError

    try:
        reader = Reader(bag)
        reader.open()
        return reader
    except ReaderError as error:
        raise ConvertError(f"{bag} is not a ROS 2 bag that can be read: {error}") from None


def _readable(reader: Any, connections: list[Any], result: BagConversion) -> Iterator[tuple[Any, Any, Any]]:
    """The reader's messages up to the first it cannot read: whatever it raises there (rosbags,
    sqlite, a decompressor), the bag is unreadable from that point on; `result.cut` says why."""
    try:
        yield from reader.messages(connections=connections)
    except Exception as error:  # noqa: BLE001 - any reader's damage ends the readable part
        result.cut = cut_reason(error)
    if result.cut is None:
        result.cut = getattr(reader, "cut", None)  # the direct reader stops by itself and says where
    result.damaged_chunks = list(getattr(reader, "damaged", []))  # and skips a damaged chunk
    result.unread_summaries = list(getattr(reader, "unread_summaries", []))


def _definitions(connections: list[Any]) -> tuple[dict[str, tuple[list[Any], list[Any]]], dict[str, str]]:
    """The Jazzy store's definitions, overridden by those the bag recorded with its topics; and the
    types whose recorded definition rosbags cannot parse, with why (not guessed from the store:
    the bag's bytes follow the definition it recorded)."""
    from rosbags.typesys import Stores, TypesysError, get_typestore

    definitions = dict(get_typestore(Stores.ROS2_JAZZY).fielddefs)
    unreadable: dict[str, str] = {}
    for connection in connections:
        text = getattr(connection.msgdef, "data", "") or ""
        if text.strip():
            try:
                definitions.update(definitions_from_msgdef(connection.msgtype, text))
            except TypesysError as error:
                unreadable[connection.msgtype] = f"its recorded definition does not parse: {error}"
    return definitions, unreadable


def _channels(connections: list[Any], refused: dict[str, str], result: BagConversion) -> list[Any]:
    """The connections that get a channel; the others' topics, with why, in `result.skipped`."""
    chosen = []
    owner: dict[str, str] = {}
    for connection in connections:
        topic, channel = connection.topic, lcm_channel(connection.topic)  # the live routes' rule too
        if connection.msgtype in refused:
            result.skipped[topic] = f"{connection.msgtype}: {refused[connection.msgtype]}"
        elif owner.get(channel, topic) != topic:
            result.skipped[topic] = f"its channel {channel} is already {owner[channel]}'s"
        elif result.channels.get(topic) is None:
            owner[channel] = topic
            result.channels[topic] = channel
            chosen.append(connection)
        else:  # the same topic recorded twice (two connections): one channel
            chosen.append(connection)
    return chosen


def _progress_total(reader: Any, chosen: list[Any]) -> tuple[int | None, Callable[[int], str]]:
    """The messages of the `chosen` topics, when the bag says how many (an MCAP file's statistics,
    a `.db3`'s rows, rosbags' metadata): the progress' total (None: not known); and how it says
    how far it has come."""
    if isinstance(reader, DirectReader):
        total = reader.message_count(chosen) or None
    else:
        total = sum(connection.msgcount for connection in chosen) or None
    if total is None:
        return None, lambda done: f"{done:,} messages"
    return total, lambda done: f"{done:,} of {total:,} messages"


def _no_progress(count: int) -> None:
    pass


def _events(
    messages: Iterator[tuple[Any, Any, Any]],
    by_id: dict[int, Any],
    result: BagConversion,
    stop: threading.Event,
    advance: Callable[[int], None],
) -> Iterator[LcmEvent]:
    # per message; into `result` at the end
    counts = dict.fromkeys((topic for topic, _, _ in by_id.values()), 0)
    try:
        for connection, timestamp_ns, data in messages:
            if stop.is_set():
                break
            advance(1)
            topic, channel, encoder = by_id[connection.id]
            # sqlite keeps any type in any column
            if type(timestamp_ns) is not int or type(data) not in _DATA:
                _damaged(result, topic, timestamp_ns, data)
                continue
            try:
                lcm = encoder.encode(bytes(data) if len(data) <= _COPY_UP_TO else data)
            except DecodeError as error:  # one bad message: counted, and the rest go on
                result.bad[topic] += 1
                result.first_error.setdefault(topic, str(error))
                continue
            counts[topic] += 1
            yield LcmEvent(channel, lcm, timestamp_ns // 1000)
    finally:
        result.written.update({topic: count for topic, count in counts.items() if count})


_DATA = (bytes, memoryview)


def _damaged(result: BagConversion, topic: str, timestamp_ns: object, data: object) -> None:
    result.damaged[topic] += 1
    result.first_damage.setdefault(topic, f"a row holds {type(timestamp_ns).__name__} {timestamp_ns!r:.20} as its "
                                          f"time and {type(data).__name__} as its data")  # fmt: skip


def _nested(mapping: LcmFromRos, names: set[str]) -> set[str]:
    """`names` and every ROS 2 type they nest."""
    found: set[str] = set()
    pending = list(names)
    while pending:
        name = pending.pop()
        if name not in found:
            found.add(name)
            pending.extend(f.nested for f in mapping.structs[name].fields if f.nested)
    return found
