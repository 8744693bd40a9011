"""Benchmark: camera images, Drake's lcmt_image_array -> sensor_msgs/Image, beside their floors.

Run: .venv/bin/python bench/images.py [--quick]

The images are real: the test scene (viewer_bridge/examples/cameras.py) rendered by RenderEngineVtk at
1280x720 and published by Drake's own ApplyCameraConfig (zlib level 1, as Drake sends them).
1. zlib: one 1280x720 RGBA image, from the array's bytes to the Image CDR (read the array, the
   bounded inflate, the CDR with its one copy of the rows), beside `zlib.decompress` of the same
   bytes into a buffer of the right size: the floor, one decompression (goal: <= 1.3x).
2. Uncompressed: the same image sent raw, array bytes to Image CDR, beside one copy of its rows
   (`bytes` of a memoryview): the floor, since an Image of its own needs one (goal: <= 1.3x).
3. Three 1280x720 cameras (rgb + depth, zlib) at 30 Hz through the router: the bridge as a process
   on its built-in config, pinned to one core; this process publishes the captured arrays on LCM
   and a raw rclpy subscriber counts the Images on the six topics. Reported: the share of images
   the subscriber got (goal >= 99%), where the others were lost (LCM into the bridge, the bridge's
   own publishing, DDS to the subscriber: from the bridge's stats), and the bridge's CPU share.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common import Measure, Size, best_of  # bench/ is on sys.path when run as a script

from viewer_bridge.config.bridge import DEFAULT_CONFIG
from viewer_bridge.formats.drake.image import images_to_lcm, read_image_array, unpack
from viewer_bridge.formats.ros.image import image_to_cdr
from viewer_bridge.transports.lcm import LcmBus

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/ (the camera scene)
WIDTH, HEIGHT = 1280, 720
STAMP = (1, 0)


def drake_arrays(cameras: int) -> list[bytes]:
    """One lcmt_image_array (rgb + depth, zlib) per camera, as ApplyCameraConfig publishes them."""
    from pydrake.lcm import DrakeLcm

    from viewer_bridge.examples.cameras import build_simulator

    lcm = DrakeLcm("memq://")
    sent: dict[str, bytes] = {}
    lcm.SubscribeAllChannels(lambda channel, data: sent.setdefault(channel, bytes(data)))
    names = {f"bench{index}": (WIDTH, HEIGHT, True) for index in range(cameras)}
    build_simulator(lcm, names, label=False).AdvanceTo(0.0)
    while lcm.HandleSubscriptions(0):
        pass
    return [sent[f"DRAKE_RGBD_CAMERA_IMAGES_{name}"] for name in names]


def to_image_cdr(data: bytes, index: int) -> bytes:
    """The route's work for one image of an array: read, unpack, write."""
    return image_to_cdr(unpack(read_image_array(data).images[index]), "camera", STAMP)


def single_image(data: bytes, size: Size = Size.FULL) -> tuple[float, float, float, float]:
    """(ours zlib, floor zlib, ours raw, floor raw), seconds per image, for the array's rgb image."""
    repeat, number = size.pick(full=(7, 20), quick=(7, 20), smoke=(1, 1))
    array = read_image_array(data)
    rgb = next(index for index, packed in enumerate(array.images) if packed.name == "rgb")
    packed = array.images[rgb]
    image_bytes = packed.row_stride * packed.height
    compressed = bytes(packed.data)
    raw = images_to_lcm([unpack(packed)], packed.time_us)
    rows = memoryview(unpack(read_image_array(raw).images[0]).pixels.reshape(-1))
    return (
        best_of(lambda: to_image_cdr(data, rgb), repeat, number),
        best_of(lambda: zlib.decompress(compressed, bufsize=image_bytes), repeat, number),
        best_of(lambda: to_image_cdr(raw, 0), repeat, number),
        best_of(lambda: bytes(rows), repeat, number),
    )


class Counter:
    """A raw rclpy subscriber counting the messages on each topic."""

    def __init__(self, topics: list[str]) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from viewer_bridge.transports.ros2 import message_class, qos_profile

        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node("bench_images", context=self.context)
        self.counts = dict.fromkeys(topics, 0)
        for topic in topics:
            self.node.create_subscription(
                message_class("sensor_msgs/msg/Image"), topic, self._counter(topic), qos_profile(10), raw=True
            )
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        threading.Thread(target=self.executor.spin, daemon=True).start()

    def _counter(self, topic: str):  # type: ignore[no-untyped-def]
        def count(data: bytes) -> None:
            self.counts[topic] += 1

        return count

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


@dataclass
class Delivery:
    """What happened to the images of a run: published (arrays x 2), the arrays the bridge took in,
    the Images it published, those the subscriber got, and the bridge's CPU share of its core."""

    published: int
    bridge_in: int
    bridge_out: int
    received: int
    cpu_share: float

    def percent(self, count: int) -> float:
        return 100.0 * count / max(self.published, 1)


def three_cameras(arrays: list[bytes], seconds: float, rate_hz: float = 30.0) -> Delivery:
    """`arrays` (one per camera) published at `rate_hz` through the bridge, pinned to CPU 0."""
    from router import URL, Bridge  # bench/router.py: the bridge as a pinned process on URL, its CPU time

    channels = [f"DRAKE_RGBD_CAMERA_IMAGES_cam{index}" for index in range(len(arrays))]
    topics = [
        f"/drake/cameras/cam{index}/{port}/image" for index in range(len(arrays)) for port in ("rgb", "depth")
    ]
    everywhere = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {1})  # the publisher and the subscriber; the bridge gets CPU 0
    with tempfile.TemporaryDirectory() as folder:
        bridge = Bridge(DEFAULT_CONFIG, Path(folder), core=0)
        counter = Counter(topics)
        bus = LcmBus(URL)
        try:
            deadline = time.monotonic() + 60  # until discovery has matched every topic (lazy routes wake)
            while min(counter.counts.values()) == 0 and time.monotonic() < deadline:
                for channel, data in zip(channels, arrays, strict=True):
                    bus.publish(channel, data)
                time.sleep(1 / rate_hz)
            stats_before = _route_counts(_next_snapshot(bridge))  # the warm-up's, all of it
            before = sum(counter.counts.values())
            cpu_before, started = bridge.cpu_seconds(), time.monotonic()
            sent = 0
            while (now := time.monotonic()) - started < seconds:
                for channel, data in zip(channels, arrays, strict=True):
                    bus.publish(channel, data)
                sent += 1
                time.sleep(max(0.0, started + sent / rate_hz - now))
            cpu = bridge.cpu_seconds() - cpu_before
            wall = time.monotonic() - started
            published = sent * len(topics)
            settle = time.monotonic() + 10  # what is in flight still counts
            while sum(counter.counts.values()) - before < published and time.monotonic() < settle:
                time.sleep(0.05)
            received = sum(counter.counts.values()) - before
        finally:
            bus.close()
            counter.close()
            bridge.stop()  # its last stats are written as it stops
            os.sched_setaffinity(0, everywhere)
        stats_after = _route_counts(bridge.snapshot())
    arrays_in, images_out = (after - first for after, first in zip(stats_after, stats_before, strict=True))
    return Delivery(published, 2 * arrays_in, images_out, received, 100.0 * cpu / wall)


def _next_snapshot(bridge: Any) -> dict[str, Any]:
    """The bridge's stats as it writes them next (every second): nothing before this call is left out."""
    written = bridge.stats.stat().st_mtime_ns if bridge.stats.exists() else 0
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and (
        not bridge.stats.exists() or bridge.stats.stat().st_mtime_ns == written
    ):
        time.sleep(0.05)
    snapshot: dict[str, Any] = bridge.snapshot()
    return snapshot


def _route_counts(snapshot: dict[str, Any]) -> tuple[int, int]:
    route = snapshot.get("camera_images", {})
    return int(route.get("messages_in", 0)), int(route.get("messages_out", 0))


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Issue 23's speed goals: one zlib image against one decompression, a raw one against one
    copy, and three 1280x720 cameras at 30 Hz through the router on one core."""
    arrays = drake_arrays(3)
    ours_zlib, floor_zlib, ours_raw, floor_raw = single_image(arrays[0], size)
    run = three_cameras(arrays, size.pick(full=15.0, quick=4.0, smoke=0.5))
    delivered = run.percent(run.received)
    return [
        Measure("zlib 1280x720 RGBA -> sensor_msgs/Image CDR, vs zlib.decompress alone", ours_zlib * 1e3,
                floor_zlib * 1e3, "ms", "<= 1.3x the decompression", ours_zlib <= 1.3 * floor_zlib),
        Measure("uncompressed 1280x720 RGBA -> Image CDR, vs one copy of its rows", ours_raw * 1e3, floor_raw * 1e3,
                "ms", "<= 1.3x one copy", ours_raw <= 1.3 * floor_raw),
        Measure(f"3 cameras 1280x720 rgb+depth at 30 Hz, bridge on one core: Images a raw rclpy subscriber got "
                f"({run.published} sent)", delivered, None, "%", ">= 99", delivered >= 99.0),
        Measure("same: arrays the bridge took in off LCM (x 2 images)", run.percent(run.bridge_in), None, "%",
                "none: where images were lost", None),
        Measure("same: Images the bridge published", run.percent(run.bridge_out), None, "%",
                "none: where images were lost", None),
        Measure("same: the bridge's CPU share of its core", run.cpu_share, None, "%", "reported", None),
    ]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    for row in measures(Size.QUICK if args.quick else Size.FULL):
        baseline = (
            ""
            if row.baseline is None
            else f" (baseline {row.baseline:.3g}, ratio {row.ours / row.baseline:.2f}x)"
        )
        print(f"{row.name}: {row.ours:.3g} {row.unit}{baseline}  goal {row.goal}: {row.met}")


if __name__ == "__main__":
    main()
