"""An index of an LCM log: where each event starts, its time and its channel, built in one pass.

An LCM log is a run of events, each `sync word 0xEDA1DA01 | u64 event number | u64 utime |
u32 channel length | u32 data length | channel | data`, big-endian. `LogIndex.build` reads the
headers through a memory map (the data is never copied) and keeps three numpy arrays sorted by
time, plus, per channel, the positions of that channel's events: "the last event of channel c
before time t" is then two binary searches, however big the log (`latched`), which is what a
seek re-sends.

A log that ends in a partial event (a logger killed mid-write) is indexed up to its last whole
event; bytes that are no event (a damaged stretch) are skipped to the next sync word; events out
of time order (a log merged from two) are played in time order. Each is said once, with where.
"""

from __future__ import annotations

import array
import logging
import mmap
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from viewer_bridge.errors import LogError

log = logging.getLogger("viewer_bridge")

SYNC = 0xEDA1DA01
_SYNC_BYTES = SYNC.to_bytes(4, "big")
_HEADER = struct.Struct(">IqqII")  # sync, event number, utime, channel length, data length
MAX_CHANNEL_LENGTH = 256  # LCM's own limit on a channel name; longer is no event
MAX_CHANNELS = 100_000  # distinct channel names one log may hold (each costs an array)

Progress = Callable[[int, int], None]  # (bytes indexed, bytes in all)


@dataclass(frozen=True, slots=True)
class LoggedEvent:
    """One event of an indexed log: its channel, data (a copy) and time in microseconds."""

    channel: str
    data: bytes
    utime: int


class LogIndex:
    """Every whole event of an LCM log, by time: `offsets`, `utimes` (microseconds), `channel_ids`
    (into `channels`), and per channel the positions of its events (`by_channel`)."""

    def __init__(
        self,
        path: Path,
        mapped: mmap.mmap | None,
        offsets: npt.NDArray[np.int64],
        utimes: npt.NDArray[np.int64],
        channel_ids: npt.NDArray[np.int32],
        channels: tuple[str, ...],
    ) -> None:
        self.path = path
        self._mapped = mapped
        self.offsets = offsets
        self.utimes = utimes
        self.channel_ids = channel_ids
        self.channels = channels
        order = np.argsort(channel_ids, kind="stable")  # positions grouped by channel, each group ascending
        bounds = np.searchsorted(channel_ids[order], np.arange(len(channels) + 1))
        self.by_channel = tuple(order[bounds[c] : bounds[c + 1]] for c in range(len(channels)))

    @classmethod
    def build(cls, path: str | Path, progress: Progress | None = None) -> LogIndex:
        """Index the log at `path` (raises `LogError` when it does not start like an LCM log)."""
        path = Path(path)
        with open(path, "rb") as file:
            size = file.seek(0, 2)
            if size == 0:
                return cls(path, None, *_empty())
            mapped = mmap.mmap(file.fileno(), 0, access=mmap.ACCESS_READ)
        if mapped[:4] != _SYNC_BYTES:
            start = mapped[:4].hex()
            mapped.close()
            raise LogError(
                f"{path} is not an LCM log: it starts with {start}, not the event sync word {SYNC:08x}"
            )
        offsets, utimes, ids, channels = _scan(path, mapped, progress)
        if len(utimes) > 1 and (backward := int(np.count_nonzero(np.diff(utimes) < 0))):
            log.warning(
                "%s: %d events are earlier than the event before them: played in time order", path, backward
            )
            order = np.argsort(utimes, kind="stable")
            offsets, utimes, ids = offsets[order], utimes[order], ids[order]
        return cls(path, mapped, offsets, utimes, ids, channels)

    def __len__(self) -> int:
        return len(self.offsets)

    @property
    def first_us(self) -> int:
        return int(self.utimes[0])

    @property
    def last_us(self) -> int:
        return int(self.utimes[-1])

    def position(self, utime: int) -> int:
        """The position of the first event later than `utime` (so every event at or before it comes first)."""
        return int(np.searchsorted(self.utimes, utime, side="right"))

    def latched(self, position: int) -> list[int]:
        """The positions, in time order, of each channel's last event before `position`: the world
        as it stood there (the last load and draw of every role, the last of every other channel)."""
        lasts = []
        for events in self.by_channel:
            before = int(np.searchsorted(events, position)) - 1
            if before >= 0:
                lasts.append(int(events[before]))
        return sorted(lasts)

    def event(self, position: int) -> LoggedEvent:
        """The event at `position` (its data copied out of the map)."""
        assert self._mapped is not None
        offset = int(self.offsets[position])
        _, _, utime, channel_length, data_length = _HEADER.unpack_from(self._mapped, offset)
        start = offset + _HEADER.size + channel_length
        channel = self.channels[int(self.channel_ids[position])]
        return LoggedEvent(channel, self._mapped[start : start + data_length], utime)

    def events(self, start: int = 0) -> Iterator[LoggedEvent]:
        for position in range(start, len(self)):
            yield self.event(position)

    def close(self) -> None:
        if self._mapped is not None:
            self._mapped.close()
            self._mapped = None


def _empty() -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int32], tuple[str, ...]]:
    return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int32), ()


def _scan(
    path: Path, mapped: mmap.mmap, progress: Progress | None
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int32], tuple[str, ...]]:
    """One pass over the headers: each event's offset, time and channel id, in file order."""
    size = len(mapped)
    offsets, utimes, ids = array.array("q"), array.array("q"), array.array("i")
    channel_ids: dict[bytes, int] = {}
    unpack, header = _HEADER.unpack_from, _HEADER.size
    offset = skipped = 0
    next_progress = 1 << 24  # the progress is told every 16 MB
    # bound once: the loop runs per event, and a name looked up is dearer than a local
    add_offset, add_utime, add_id, known = offsets.append, utimes.append, ids.append, channel_ids.get
    while offset + header <= size:
        sync, _, utime, channel_length, data_length = unpack(mapped, offset)
        if sync != SYNC or channel_length > MAX_CHANNEL_LENGTH:  # no event here: on to the next sync word
            found = mapped.find(_SYNC_BYTES, offset + 1)
            found = size if found < 0 else found
            skipped += found - offset
            offset = found
            continue
        start = offset + header
        end = start + channel_length + data_length
        if end > size:
            break  # a partial last event
        name = mapped[start : start + channel_length]
        channel = known(name)
        if channel is None:
            if len(channel_ids) >= MAX_CHANNELS:
                raise LogError(f"{path}: more than {MAX_CHANNELS} channels; not indexed")
            channel = channel_ids[name] = len(channel_ids)
        add_offset(offset)
        add_utime(utime)
        add_id(channel)
        offset = end
        if offset >= next_progress and progress is not None:
            next_progress = offset + (1 << 24)
            progress(offset, size)
    if progress is not None:
        progress(size, size)
    if skipped:
        log.warning("%s: %d bytes that are no LCM event were skipped", path, skipped)
    if offset < size:
        log.warning(
            "%s ends in a partial event: the %d bytes after byte %d are not a whole event and were skipped",
            path,
            size - offset,
            offset,
        )
    names = tuple(name.decode("utf-8", "replace") for name in channel_ids)
    return (
        np.frombuffer(offsets, np.int64).copy(),
        np.frombuffer(utimes, np.int64).copy(),
        np.frombuffer(ids, np.int32).copy(),
        names,
    )
