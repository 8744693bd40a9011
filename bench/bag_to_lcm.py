"""Benchmark: `viewer-bridge convert BAG OUT.lcmlog` (docs/PROTOCOLS.md section 14), time per MB
of bag, for an image-heavy bag and a bag of many small messages, against the obvious Python path.

Run: .venv/bin/python bench/bag_to_lcm.py [--quick]

The bags are MCAP files as rosbag2 records them (one chunked, uncompressed file; CDR by rclpy's
`serialize_message`): 640x480 rgb8 `sensor_msgs/Image`s, and 7-joint `sensor_msgs/JointState`s.
The baseline converts the same bag as a hand-written converter would: rosbags' reader, rclpy's
`deserialize_message`, lcm-gen's class of the generated `.lcm` file filled and encoded, the same LCM
log writer. The files are in /dev/shm where there is one: the disk is shared, and not what is
measured. Both run in this process in alternating rounds, the best of each; the first event of
each output is checked to be the same bytes.
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import print_measures
from ros_to_lcm import TYPES, fill_image, fill_joint_state, image, joint_state, lcmgen_classes

from viewer_bridge.cli.bag_to_lcm import bag_to_lcm
from viewer_bridge.lcmcodec.from_ros import lcm_channel, load_ros_definitions, map_ros_types
from viewer_bridge.transports.lcm import LcmEvent, read_log, write_log

MB = 1e6
# the bags and logs in memory: the conversion is measured, not the disk (others share it)
RAM = Path("/dev/shm")
GOAL_MB_S = 100.0  # the image bag


def write_bag(path: Path, topic: str, ros_type: str, messages: list[Any]) -> None:
    """An MCAP file of `messages` (rclpy messages of `ros_type`) on `topic`, a millisecond apart."""
    from mcap.writer import CompressionType, Writer
    from rclpy.serialization import serialize_message
    from rosbags.typesys import Stores, get_typestore

    msgdef = get_typestore(Stores.ROS2_JAZZY).generate_msgdef(ros_type, ros_version=2)[0]
    with path.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        writer.start(profile="ros2")
        schema = writer.register_schema(ros_type, "ros2msg", msgdef.encode())
        channel = writer.register_channel(topic, "cdr", schema)
        for index, message in enumerate(messages):
            data = serialize_message(message)
            writer.add_message(channel, log_time=index * 1_000_000, data=data, publish_time=index * 1_000_000)
        writer.finish()


def baseline(bag: Path, out: Path, ros_class: Any, lcm_class: Any, fill: Callable[[Any, Any], None]) -> None:
    """rosbags' reader, rclpy's `deserialize_message`, lcm-gen's class filled by `fill` and encoded."""
    from rclpy.serialization import deserialize_message
    from rosbags.rosbag2 import Reader

    def events(reader: Any) -> Any:
        for connection, stamp, data in reader.messages():
            ros = deserialize_message(bytes(data), ros_class)
            message = lcm_class()
            message.header.stamp.sec, message.header.stamp.nanosec = (
                ros.header.stamp.sec,
                ros.header.stamp.nanosec,
            )
            message.header.frame_id = ros.header.frame_id
            fill(ros, message)
            yield LcmEvent(lcm_channel(connection.topic), message.encode(), stamp // 1000)

    with Reader(bag) as reader:
        write_log(out, events(reader))


def ours(bag: Path, out: Path) -> None:
    bag_to_lcm(bag, out, force=True)


def seconds(call: Callable[[], None]) -> float:
    started = time.perf_counter()
    call()
    return time.perf_counter() - started


def measures(size: Size = Size.FULL) -> list[Measure]:
    from sensor_msgs.msg import Image, JointState

    definitions, wanted = load_ros_definitions(TYPES)
    rows = []
    with tempfile.TemporaryDirectory(dir=RAM if RAM.is_dir() else None) as folder_name:
        folder = Path(folder_name)
        classes = lcmgen_classes(map_ros_types(definitions, wanted), folder / "lcmgen")
        frames = size.pick(full=100, quick=40, smoke=3)
        width, height = size.pick(full=(640, 480), quick=(640, 480), smoke=(8, 6))
        states = size.pick(full=50_000, quick=20_000, smoke=50)
        bags = [
            ("images", f"{frames} sensor_msgs/Image {width}x{height} rgb8", "/camera/image", TYPES[1],
             [image(width, height) for _ in range(frames)], Image, fill_image, f"ms/MB <= {1000 / GOAL_MB_S:g} "
             f"(>= {GOAL_MB_S:g} MB/s)", 1000 / GOAL_MB_S),
            ("joints", f"{states} sensor_msgs/JointState (7 joints)", "/joint_states", TYPES[0],
             [joint_state(7)] * states, JointState, fill_joint_state, "ratio >= 5x", None),
        ]  # fmt: skip
        for name, what, topic, ros_type, messages, ros_class, fill, goal, limit in bags:
            bag, mine, theirs = (
                folder / f"{name}.mcap",
                folder / f"{name}.lcmlog",
                folder / f"{name}_base.lcmlog",
            )
            write_bag(bag, topic, ros_type, messages)
            megabytes = bag.stat().st_size / MB
            ours_best = base_best = float("inf")
            for _ in range(size.pick(full=3, quick=2, smoke=1)):  # alternating rounds: the load drifts
                ours_best = min(ours_best, seconds(lambda: ours(bag, mine)))  # noqa: B023 (called at once)
                base_seconds = seconds(lambda: baseline(bag, theirs, ros_class, classes[ros_type], fill))  # noqa: B023
                base_best = min(base_best, base_seconds)
            assert next(iter(read_log(mine))) == next(iter(read_log(theirs)))  # noqa: S101 (like with like)
            ms_per_mb, base_ms_per_mb = ours_best * 1000 / megabytes, base_best * 1000 / megabytes
            met = ms_per_mb <= limit if limit is not None else base_ms_per_mb / ms_per_mb >= 5
            rows.append(Measure(f"convert bag of {what} ({megabytes:.0f} MB): {megabytes / ours_best:.0f} MB/s, "
                                "vs rosbags + rclpy + lcm-gen", ms_per_mb, base_ms_per_mb, "ms/MB", goal, met))  # fmt: skip
    return rows


if __name__ == "__main__":
    print_measures(measures(Size.QUICK if "--quick" in sys.argv[1:] else Size.FULL))
