"""Benchmark: `viewer-bridge play`'s log index (viewer_bridge/transports/lcm_log_index.py): how fast
a log is indexed, and how long a seek takes to find the world at its instant, against reading the
log with LCM's own reader (what a replay from the start does).

Run: .venv/bin/python bench/playback.py [--quick]

The log is written here: a Drake-like mix of 1 kHz draws (1.4 kB), a load every 10 s (200 kB),
and 100 Hz status messages on 20 channels, up to the size measured (100 MB; 1 GB in the full
run). It lives in /dev/shm where there is one: the disk is shared, and not what is measured (a
cold read from a disk runs at that disk's speed). The index is built with LCM's event log reader
as the baseline over the same file. A seek's latency is the position of the instant (a binary
search) and the world there (each channel's last event before it, read out of the map), for 200
instants spread over the log; its baseline is reading the log from its start to the middle, as a
replay that can only go forward would; and the same through a paused player, from the request
to the last message of that world delivered to a subscriber. Last, the CPU each event costs a
player at full speed against `run --lcm-url 'file://LOG?speed=0'`'s replay (the routes behind
either cost the same, and are not measured here).
"""

from __future__ import annotations

import random
import struct
import sys
import tempfile
import threading
import time
from pathlib import Path

from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import print_measures

from viewer_bridge.transports.lcm import LogReplay, read_log
from viewer_bridge.transports.lcm_log_index import SYNC, LogIndex
from viewer_bridge.transports.lcm_playback import LogPlayer
from viewer_bridge.transports.playback import PlaybackRequest

MB = 1e6
RAM = Path("/dev/shm")
GOAL_SEEK_MS = 50.0  # issue 53: < 50 ms from request to the state at the seek point
GOAL_INDEX_MB_S = 200.0


def write_log(path: Path, size_bytes: int) -> int:
    """A log of about `size_bytes`: 1 kHz draws, a load every 10 s, 20 status channels at 100 Hz."""
    header = struct.Struct(">IqqII")
    draw, load, status = bytes(1400), bytes(200_000), bytes(60)
    t0 = 1_700_000_000_000_000
    number = written = 0
    with path.open("wb") as file:
        step = 0
        while written < size_bytes:
            utime = t0 + step * 1000
            events = [(b"DRAKE_VIEWER_DRAW", draw)]
            if step % 10_000 == 0:
                events.insert(0, (b"DRAKE_VIEWER_LOAD_ROBOT", load))
            if step % 10 == 0:
                events += [(b"STATUS_%d" % (channel,), status) for channel in range(20)]
            for channel, data in events:
                file.write(header.pack(SYNC, number, utime, len(channel), len(data)) + channel + data)
                written += header.size + len(channel) + len(data)
                number += 1
            step += 1
    return number


def lcm_reader_seconds(path: Path) -> float:
    started = time.perf_counter()
    for _ in read_log(path):
        pass
    return time.perf_counter() - started


def to_middle_seconds(path: Path, middle_us: int) -> float:
    """Read with LCM's reader from the start up to `middle_us`: a forward-only replay's seek."""
    started = time.perf_counter()
    for event in read_log(path):
        if event.timestamp_us >= middle_us:
            break
    return time.perf_counter() - started


def seek_ms(index: LogIndex, instants: list[int]) -> list[float]:
    spent = []
    for instant in instants:
        started = time.perf_counter()
        world = [index.event(position) for position in index.latched(index.position(instant))]
        spent.append((time.perf_counter() - started) * 1000)
        assert world  # noqa: S101 (every instant has a load and a draw before it)
    return spent


def player_seek_ms(index: LogIndex, instants: list[int]) -> list[float]:
    """A paused player's seeks: from the request to the last message of the world there delivered
    to a subscriber (on the player's thread: its wake-up included)."""
    delivered = threading.Semaphore(0)
    expected = {"count": 0, "seen": 0}

    def arrived(channel: str, data: bytes, received_us: int) -> None:
        expected["seen"] += 1
        if expected["seen"] == expected["count"]:
            delivered.release()

    player = LogPlayer(index, paused=True)
    player.subscribe(".*", arrived)
    expected["count"] = len(index.latched(index.position(index.first_us)))
    player.start()
    delivered.acquire()
    spent = []
    for instant in instants:
        expected["count"], expected["seen"] = len(index.latched(index.position(instant))), 0
        started = time.perf_counter()
        player.request(PlaybackRequest(play=False, speed=1.0, seek_ns=instant * 1000))
        delivered.acquire()
        spent.append((time.perf_counter() - started) * 1000)
    player.close()
    return spent


def cpu_per_event_us(source: LogPlayer | LogReplay, count: int) -> float:
    """CPU (this process's, all threads) per event a source delivers to a subscriber that keeps
    nothing, as fast as it can."""
    delivered = threading.Semaphore(0)
    seen = [0]

    def arrived(channel: str, data: bytes, received_us: int) -> None:
        seen[0] += 1
        if seen[0] == count:
            delivered.release()

    source.subscribe(".*", arrived)
    started = time.process_time()
    source.start()
    delivered.acquire()
    spent = time.process_time() - started
    source.close()
    return spent / count * 1e6


def measures(size: Size = Size.FULL) -> list[Measure]:
    sizes = size.pick(full=[100_000_000, 1_000_000_000], quick=[100_000_000], smoke=[2_000_000])
    rows = []
    with tempfile.TemporaryDirectory(dir=RAM if RAM.is_dir() else None) as folder_name:
        for size_bytes in sizes:
            path = Path(folder_name) / "log.lcmlog"
            count = write_log(path, size_bytes)
            megabytes = path.stat().st_size / MB
            best = base = float("inf")
            for _ in range(size.pick(full=3, quick=2, smoke=1)):  # alternating rounds: the load drifts
                started = time.perf_counter()
                index = LogIndex.build(path)
                best = min(best, time.perf_counter() - started)
                base = min(base, lcm_reader_seconds(path))
                if len(index) != count:
                    raise AssertionError(f"indexed {len(index)} of {count} events")
                index.close()
            rows.append(Measure(f"index a {megabytes:.0f} MB log ({count} events): {megabytes / best:.0f} MB/s, "
                                "vs LCM's reader", best * 1000 / megabytes, base * 1000 / megabytes, "ms/MB",
                                f">= {GOAL_INDEX_MB_S:g} MB/s", megabytes / best >= GOAL_INDEX_MB_S))  # fmt: skip
            index = LogIndex.build(path)
            first, last = index.first_us, index.last_us
            instants = [random.Random(seed).randint(first, last) for seed in range(200)]
            spent = sorted(seek_ms(index, instants))
            median, worst = spent[len(spent) // 2], spent[-1]
            middle = to_middle_seconds(path, (first + last) // 2) * 1000
            rows.append(Measure(f"seek in a {megabytes:.0f} MB log: the world at an instant (max {worst:.2f} ms), "
                                "vs reading to it", median, middle, "ms", f"<= {GOAL_SEEK_MS:g} ms",
                                worst <= GOAL_SEEK_MS))  # fmt: skip
            played = sorted(player_seek_ms(index, instants[:50]))  # the player closes the index
            median, worst = played[len(played) // 2], played[-1]
            rows.append(Measure(f"seek a player of it: request to the world delivered (max {worst:.2f} ms), "
                                "vs reading to it", median, middle, "ms", f"<= {GOAL_SEEK_MS:g} ms",
                                worst <= GOAL_SEEK_MS))  # fmt: skip
            ours_us = cpu_per_event_us(LogPlayer(LogIndex.build(path), speed=1e9), count)
            base_us = cpu_per_event_us(LogReplay(path, speed=0), count)
            rows.append(Measure(f"play a {megabytes:.0f} MB log as fast as it goes: CPU per event, "
                                "vs run's replay (file://LOG?speed=0)", ours_us, base_us, "us",
                                "<= the replay's", ours_us <= base_us))  # fmt: skip
            path.unlink()
    return rows


if __name__ == "__main__":
    print_measures(measures(Size.QUICK if "--quick" in sys.argv[1:] else Size.FULL))
