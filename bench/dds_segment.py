"""Benchmark: what a larger Fast DDS shared-memory segment (`ros.shared_memory_mb`) saves.

Run: .venv/bin/python bench/dds_segment.py [--seconds 8] [--rounds 2]

No router: the ros transport itself (`RosTransport`, as the bridge makes it) publishes the three
per-draw messages of a 1000-link scene at 2 kHz (its world-frame MarkerArray, 248 kB, latched as
the `markers` route publishes it; its TFMessage; its PoseArray, with the default config's QoS),
and raw rclpy subscribers in a process of their own (`common.DdsCounter`) count what arrives.
Each publisher runs in a process of its own, since Fast DDS reads its profile once per process:
with a 32 MiB segment (`shared_memory_mb: 32`), and with Fast DDS's own 512 KiB (`0`, the
default), in turn. Reported: the messages the subscribers got, of those published, per topic; the better of
`--rounds` rounds, interleaved. Nothing is pinned.
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from typing import Any

from common import DdsCounter, Measure, Size, paced, settle
from router import DISCOVERY_S, frame, scene

TOPICS = {  # key -> (topic, type)
    "markers": ("/bench/segment/markers", "visualization_msgs/msg/MarkerArray"),
    "tf": ("/bench/segment/tf", "tf2_msgs/msg/TFMessage"),
    "poses": ("/bench/segment/poses", "geometry_msgs/msg/PoseArray"),
}
LINKS = 1000
RATE_HZ = 2000.0
SEGMENTS = {"32 MiB": 32, "512 KiB (Fast DDS's own)": 0}


def payloads() -> dict[str, list[bytes]]:
    """Each topic's CDR for 32 draws of the scene, published in turn."""
    from viewer_bridge.convert import draw_to_pose_array, draw_to_tf
    from viewer_bridge.formats.drake.draw import DrawEncoder
    from viewer_bridge.formats.ros.markers import MarkerStream

    the_scene = scene(LINKS)
    names = tuple(link.name for link in the_scene.links)
    draws = [frame(names, sequence) for sequence in range(1, 33)]
    encoded = [DrawEncoder().encode(draw) for draw in draws]
    markers = MarkerStream(the_scene)
    return {
        "markers": [markers.update(draw) for draw in draws],
        "tf": [draw_to_tf(data) for data in encoded],
        "poses": [draw_to_pose_array(data) for data in encoded],
    }


def publisher_child(megabytes: int, seconds: float, start: Any, published: Any) -> None:
    """The publishing process: a ros transport with a segment of `megabytes`, once `start` is set
    (the subscribers matched), the three topics at `RATE_HZ` for `seconds`; `published[i]` counts."""
    from viewer_bridge.transports.base import CDR, MessageType, Qos
    from viewer_bridge.transports.ros2 import RosSettings, RosTransport

    transport = RosTransport(RosSettings(node="viewer_bridge", shared_memory_mb=megabytes))
    publishers = [transport.publisher(topic, MessageType(typename, CDR), Qos(depth=10, latched=key == "markers"))
                  for key, (topic, typename) in TOPICS.items()]  # fmt: skip
    data = payloads()
    each = [data[key] for key in TOPICS]
    transport.start()
    start.wait(60)

    def publish(sent: int) -> None:
        for index, publisher in enumerate(publishers):
            publisher.publish(each[index][sent % 32])
            published[index] += 1

    paced(publish, 0, RATE_HZ, seconds)
    time.sleep(1.0)  # what is in flight arrives before the transport closes
    transport.close()


def run(label: str, megabytes: int, seconds: float) -> dict[str, float]:
    """One publisher process: per topic, the share of what it published that the subscribers got."""
    spawn = multiprocessing.get_context("spawn")
    counter = DdsCounter(TOPICS)
    counter.counting.set()
    start, published = spawn.Event(), spawn.Array("q", len(TOPICS), lock=False)
    process = spawn.Process(target=publisher_child, args=(megabytes, seconds, start, published))
    process.start()
    try:
        settle(counter.sees_bridge, DISCOVERY_S)
        time.sleep(1.0)  # discovery matches every topic's endpoints once the node is seen
        start.set()
        process.join(seconds + 60)
        settle(lambda: counter.count >= sum(published), 2.0)
    finally:
        if process.is_alive():
            process.kill()
        counter.close()
    result = {key: 100.0 * counter.counts[key] / max(published[index], 1) for index, key in enumerate(TOPICS)}
    result["published"] = float(published[0])
    print(f"   {label:<26} published {published[0]} of each; got " + ", ".join(
        f"{key} {result[key]:5.1f}%" for key in TOPICS), flush=True)  # fmt: skip
    return result


def compare(seconds: float, rounds: int) -> dict[str, dict[str, float]]:
    best: dict[str, dict[str, float]] = {}
    print(f"{LINKS}-link scene's MarkerArray, TFMessage and PoseArray at {RATE_HZ:g} Hz for {seconds:g} s, "
          "one node to raw rclpy subscribers")  # fmt: skip
    for _ in range(rounds):
        for label, megabytes in SEGMENTS.items():
            result = run(label, megabytes, seconds)
            if label not in best or min(result[key] for key in TOPICS) > min(
                best[label][key] for key in TOPICS
            ):
                best[label] = result
    return best


def measures(size: Size = Size.FULL) -> list[Measure]:
    best = compare(size.pick(full=8.0, quick=4.0, smoke=0.5), size.pick(full=2, quick=1, smoke=1))
    ours, theirs = best["32 MiB"], best["512 KiB (Fast DDS's own)"]
    return [
        Measure(
            f"dds_segment: {key} messages an rclpy subscriber got of those published, 1000-link scene's three "
            "per-draw topics at 2 kHz from one node, ros.shared_memory_mb: 32 (baseline: 0, the default: "
            "Fast DDS's own 512 KiB segment)",
            ours[key],
            theirs[key],
            "%",
            ">= 99.9",
            ours[key] >= 99.9,
        )  # fmt: skip
        for key in TOPICS
    ]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    compare(args.seconds, args.rounds)


if __name__ == "__main__":
    main()
