"""Benchmark: MCAP read and written, to choose one reader and one writer for the package.

Run: .venv/bin/python bench/mcap_files.py [--quick]

Read: the bag reader of `convert BAG OUT.lcmlog` (`viewer_bridge/cli/bag_files.py`) against the
mcap library's own reader (`mcap.reader.make_reader(...).iter_messages()`), both checking the
chunks' CRCs (ours always does), every message of the same file touched once (its length
summed). Written: the ros2 profile's CDR messages through the foxglove-sdk's MCAP writer (the one
the mcap transport uses for both profiles) against the mcap library's `Writer`. Two files: many
small messages in zstd chunks (both writers' default), and 1 MB messages of noise (an image does
not compress much) in uncompressed chunks, as rosbag2 records by default. Files live in /dev/shm where
there is one: the disk is shared and not what is measured. Alternating rounds, the best of each.
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import print_measures

from viewer_bridge.cli.bag_files import DirectReader

RAM = Path("/dev/shm")
JOINT_STATE = "sensor_msgs/msg/JointState"


def _definition() -> str:
    from rosbags.typesys import Stores, get_typestore

    return str(get_typestore(Stores.ROS2_JAZZY).generate_msgdef(JOINT_STATE, ros_version=2)[0])


def _payloads(count: int, size: int) -> list[bytes]:
    if size < 1000:
        return [bytes([index % 251]) * size for index in range(count)]
    noise = np.random.default_rng(0).integers(0, 256, size + count, dtype=np.uint8).tobytes()
    return [noise[index : index + size] for index in range(count)]


def write_with_mcap(path: Path, payloads: list[bytes], definition: str, zstd: bool) -> None:
    from mcap.writer import CompressionType, Writer

    with path.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD if zstd else CompressionType.NONE)
        writer.start(profile="ros2", library="bench")
        schema = writer.register_schema(JOINT_STATE, "ros2msg", definition.encode())
        channel = writer.register_channel("/joint_states", "cdr", schema)
        for index, data in enumerate(payloads):
            writer.add_message(channel, index * 1000, data, index * 1000)
        writer.finish()


def write_with_foxglove(path: Path, payloads: list[bytes], definition: str, zstd: bool) -> None:
    import foxglove
    from foxglove.mcap import MCAPCompression, MCAPWriteOptions

    context = foxglove.Context()
    options = MCAPWriteOptions(profile="ros2", compression=MCAPCompression.Zstd if zstd else None)
    writer = foxglove.open_mcap(path, allow_overwrite=True, context=context, writer_options=options)
    schema = foxglove.Schema(name=JOINT_STATE, encoding="ros2msg", data=definition.encode())
    channel = foxglove.Channel("/joint_states", schema=schema, message_encoding="cdr", context=context)
    for index, data in enumerate(payloads):
        channel.log(data, log_time=index * 1000)
    writer.close()


def read_with_ours(path: Path) -> int:
    reader = DirectReader(path)
    return sum(len(data) for _, _, data in reader.messages(reader.connections))


def read_with_mcap(path: Path) -> int:
    from mcap.reader import make_reader

    with path.open("rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        return sum(len(message.data) for _, _, message in reader.iter_messages())


def _best(rounds: int, *calls: Callable[[], object]) -> list[float]:
    best = [float("inf")] * len(calls)
    for _ in range(rounds):  # alternating: the load drifts
        for index, call in enumerate(calls):
            started = time.perf_counter()
            call()
            best[index] = min(best[index], time.perf_counter() - started)
    return best


def measures(size: Size = Size.FULL) -> list[Measure]:
    rounds = size.pick(full=5, quick=3, smoke=1)
    definition = _definition()
    rows = []
    with tempfile.TemporaryDirectory(dir=RAM if RAM.is_dir() else None) as folder_name:
        folder = Path(folder_name)
        for what, count, each, zstd in (
            ("small messages, zstd", size.pick(full=200_000, quick=50_000, smoke=100), 120, True),
            ("1 MB messages, uncompressed", size.pick(full=200, quick=50, smoke=2), 1_000_000, False),
        ):
            payloads = _payloads(count, each)
            ours_file, theirs_file = folder / "foxglove.mcap", folder / "mcap.mcap"
            writes = _best(
                rounds,
                lambda: write_with_foxglove(ours_file, payloads, definition, zstd),  # noqa: B023 (called at once)
                lambda: write_with_mcap(theirs_file, payloads, definition, zstd),  # noqa: B023
            )
            assert read_with_mcap(ours_file) == read_with_mcap(theirs_file) == count * each  # noqa: S101
            reads = _best(rounds, lambda: read_with_ours(theirs_file), lambda: read_with_mcap(theirs_file))  # noqa: B023
            per_message = [seconds / count * 1e6 for seconds in (*writes, *reads)]
            rows.append(Measure(f"MCAP write, {count} {what}: foxglove-sdk vs mcap's Writer", per_message[0],
                                per_message[1], "us/msg", "faster: the one writer", writes[0] <= writes[1]))  # fmt: skip
            rows.append(Measure(f"MCAP read, {count} {what}: ours vs mcap's reader", per_message[2],
                                per_message[3], "us/msg", "faster: the one reader", reads[0] <= reads[1]))  # fmt: skip
    return rows


if __name__ == "__main__":
    print_measures(measures(Size.QUICK if "--quick" in sys.argv[1:] else Size.FULL))
