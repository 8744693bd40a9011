"""Benchmark: the router as a process, between a real LCM publisher and a real rclpy subscriber.

Run: .venv/bin/python bench/router.py [--seconds 10]

1. Throughput. The bridge is pinned to one core (CPU 0); this process (publisher and subscriber)
   runs on the other. A 1000-link scene (a load, then 1000-link draws at 1 kHz) goes through the
   `markers` and `poses` routes. Reported each second from the bridge's `--stats-json`: messages
   in and out per route, drops, and the mailbox depth (a backlog would show there).
2. Latency, LCM in -> ROS 2 out, 100 links at 100 Hz: the time from `lcm.publish` here to the
   rclpy callback here, per message (the first link's x carries a sequence number). Measured for
   the `poses` route (draw -> PoseArray) and, in the same run, for a bare byte passthrough
   (`lcm_bytes_to_ros`: the LCM bytes in a UInt8MultiArray, no translation). The first second
   of each (DDS matching, warm-up) is left out.
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from bridge.formats.drake import DrawEncoder, load_from_scene
from bridge.scene import Box, Geometry, Link, LinkPoses, Pose, Scene
from bridge.transports.lcm import LcmBus

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(101 - os.getpid() % 20))
URL = f"udpm://239.255.76.67:{7950 + os.getpid() % 40}?ttl=0"

THROUGHPUT = """\
routes:
  - name: markers
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"}
    translator: drake_to_marker_array
    destination: {transport: ros, name: /bench/markers}
  - name: poses
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: drake_to_pose_array
    destination: {transport: ros, name: /bench/poses}
"""

LATENCY = {
    "poses": """\
routes:
  - name: poses
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: drake_to_pose_array
    destination: {transport: ros, name: /bench/out}
    qos: {depth: 100}
    rate: {policy: all}
""",
    "passthrough": """\
routes:
  - name: passthrough
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: lcm_bytes_to_ros
    destination: {transport: ros, name: /bench/out}
    qos: {depth: 100}
    rate: {policy: all}
""",
}


def scene(links: int) -> Scene:
    return Scene(
        tuple(
            Link(f"plant::robot::link_{i}", 1, (Geometry(Box((0.1, 0.1, 0.1)), Pose((0.05, 0, 0))),))
            for i in range(links)
        )
    )


def frame(names: tuple[str, ...], sequence: int) -> LinkPoses:
    count = len(names)
    positions = np.zeros((count, 3))
    positions[:, 1] = np.arange(count)
    positions[0, 0] = sequence  # float32 keeps integers below 2^24 exactly
    quaternions = np.tile([1.0, 0.0, 0.0, 0.0], (count, 1))
    return LinkPoses(sequence, names, np.ones(count, np.int32), positions, quaternions)


class Bridge:
    def __init__(self, config: str, folder: Path, core: int | None) -> None:
        path = folder / "bench.yaml"
        path.write_text(config)
        self.stats = folder / "stats.json"
        self.stats.unlink(missing_ok=True)
        command = [sys.executable, "-m", "bridge.cli", "run", "-c", str(path), "--lcm-url", URL,
                   "--stats-json", str(self.stats), "--stats-period", "1"]  # fmt: skip
        preexec = (lambda: os.sched_setaffinity(0, {core})) if core is not None else None
        self.process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, preexec_fn=preexec)
        assert self.process.stderr is not None
        for line in self.process.stderr:
            if "routes running" in line:
                break
        threading.Thread(target=self.process.stderr.read, daemon=True).start()

    def snapshot(self) -> dict:  # type: ignore[type-arg]
        try:
            return json.loads(self.stats.read_text())  # type: ignore[no-any-return]
        except (OSError, ValueError):
            return {}

    def stop(self) -> None:
        self.process.send_signal(2)
        self.process.wait(timeout=20)


class Subscriber:
    """rclpy, raw bytes: counts messages and reads the sequence number back out of them."""

    def __init__(self, topic: str, typename: str) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from bridge.transports.ros2 import message_class, qos_profile

        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node("bench_subscriber", context=self.context)
        self.received: list[tuple[bytes, int]] = []
        self.node.create_subscription(
            message_class(typename), topic, lambda data: self.received.append((bytes(data), time.perf_counter_ns())),
            qos_profile(1000), raw=True,
        )  # fmt: skip
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        threading.Thread(target=self.executor.spin, daemon=True).start()

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def pose_array_sequence(data: bytes) -> int:
    from bridge.formats.ros import pose_array_arrays

    return int(pose_array_arrays(data)[2][0, 0])


def passthrough_sequence(data: bytes) -> int:
    (length,) = struct.unpack_from("<I", data, 12)
    draw = data[16 : 16 + length]
    from bridge.formats.drake import DrawDecoder

    return int(DrawDecoder().decode(draw).positions[0, 0])


def publish_at(
    bus: LcmBus, rate_hz: float, seconds: float, names: tuple[str, ...], sent: dict[int, int]
) -> None:
    encoder = DrawEncoder()
    period = 1.0 / rate_hz
    start = time.perf_counter()
    sequence = 1
    while True:
        due = start + (sequence - 1) * period
        now = time.perf_counter()
        if now - start >= seconds:
            return
        if due > now:
            time.sleep(max(0.0, due - now - 0.0005))
            while time.perf_counter() < due:
                pass
        data = encoder.encode(frame(names, sequence))
        sent[sequence] = time.perf_counter_ns()
        bus.publish("DRAKE_VIEWER_DRAW", data)
        sequence += 1


def throughput(folder: Path, seconds: float) -> None:
    links = 1000
    the_scene = scene(links)
    names = tuple(link.name for link in the_scene.links)
    bridge = Bridge(THROUGHPUT, folder, core=0)
    bus = LcmBus(URL)
    subscriber = Subscriber("/bench/poses", "geometry_msgs/msg/PoseArray")
    time.sleep(2.0)  # discovery
    bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(the_scene).encode())
    sent: dict[int, int] = {}
    publisher = threading.Thread(target=publish_at, args=(bus, 1000.0, seconds, names, sent))
    print(f"1. throughput: 1000-link draws at 1 kHz for {seconds:.0f} s, bridge pinned to CPU 0")
    print(f"{'t (s)':>6} | {'draws sent':>10} | {'poses in':>8} {'out':>8} {'dropped':>8} {'queued':>6} | "
          f"{'markers in':>10} {'out':>8} {'dropped':>8} {'queued':>6}")  # fmt: skip
    started = time.monotonic()
    publisher.start()
    while publisher.is_alive() or time.monotonic() - started < seconds + 2:
        time.sleep(1.0)
        stats = bridge.snapshot()
        if not stats:
            continue
        p, m = stats["poses"], stats["markers"]
        print(f"{time.monotonic() - started:6.1f} | {len(sent):>10} | {p['messages_in']:>8} {p['messages_out']:>8} "
              f"{p['dropped']:>8} {p['queued']:>6} | {m['messages_in']:>10} {m['messages_out']:>8} "
              f"{m['dropped']:>8} {m['queued']:>6}")  # fmt: skip
    bridge.stop()
    stats = bridge.snapshot()
    subscriber.close()
    bus.close()
    p, m = stats["poses"], stats["markers"]
    print(f"   rclpy subscriber received {len(subscriber.received)} PoseArrays of {len(sent)} draws sent")
    print(f"   translate ms p50/p99: poses {p['translate_ms']['p50']}/{p['translate_ms']['p99']}, "
          f"markers {m['translate_ms']['p50']}/{m['translate_ms']['p99']}")  # fmt: skip
    print(f"   in-bridge latency ms p50/p99: poses {p['latency_ms']['p50']}/{p['latency_ms']['p99']}, "
          f"markers {m['latency_ms']['p50']}/{m['latency_ms']['p99']}")  # fmt: skip


def latency(folder: Path, seconds: float) -> None:
    names = tuple(f"plant::robot::link_{i}" for i in range(100))
    results = {}
    for mode, typename, sequence_of in (
        ("passthrough", "std_msgs/msg/UInt8MultiArray", passthrough_sequence),
        ("poses", "geometry_msgs/msg/PoseArray", pose_array_sequence),
    ):
        bridge = Bridge(LATENCY[mode], folder, core=None)
        bus = LcmBus(URL)
        subscriber = Subscriber("/bench/out", typename)
        time.sleep(2.0)
        sent: dict[int, int] = {}
        publish_at(bus, 100.0, seconds, names, sent)
        time.sleep(0.5)
        bridge.stop()
        inside = next(iter(bridge.snapshot().values()))
        subscriber.close()
        bus.close()
        # The first second is warm-up (DDS matching, first allocations): left out of both.
        latencies = [
            (arrived - sent[sequence]) / 1e6
            for data, arrived in subscriber.received
            if (sequence := sequence_of(data)) > 100
        ]
        results[mode] = (np.percentile(latencies, [50, 99]), len(subscriber.received), len(sent), inside)
    print(f"\n2. latency, LCM publish -> rclpy callback, 100 links at 100 Hz for {seconds:.0f} s each")
    for mode, ((p50, p99), received, sent_count, inside) in results.items():
        print(
            f"   {mode:<12} p50 {p50:6.3f} ms  p99 {p99:6.3f} ms  ({received} of {sent_count} received; "
            f"inside the bridge p50 {inside['latency_ms']['p50']} p99 {inside['latency_ms']['p99']} ms, "
            f"translate p50 {inside['translate_ms']['p50']} ms)"
        )
    ratio = results["poses"][0][1] / results["passthrough"][0][1]
    print(f"   p99 ratio, translated / passthrough: {ratio:.2f} (goal: within 1.5)")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--only", choices=["throughput", "latency"], help="run one of the two parts")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        if args.only != "latency":
            throughput(Path(folder), args.seconds)
        if args.only != "throughput":
            latency(Path(folder), args.seconds)


if __name__ == "__main__":
    main()
