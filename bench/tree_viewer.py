"""Benchmark: big tree viewer requests through viewer-bridge's server, beside `json.loads`.

Run: .venv/bin/python bench/tree_viewer.py
(bench/all.py takes the same figures as rows, `measures`: quick times them shorter, smoke at 100
points and 10 ranges.)

A setgeometry with a 100,000-point pointcloud (with an rgb channel) and one with a
10,000-range planar_lidar, each as the envelope bytes a client publishes. Ours: the whole
server path (envelope decode, JSON parse, checks, the tree, the reply, the MarkerArray CDR with
POINTS). Baseline in the same process: the standard library's `json.loads` of the same JSON.
"""

from __future__ import annotations

import json
from collections.abc import Callable

import numpy as np
from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import seconds_per_call

from viewer_bridge.formats.tree_viewer.envelope import FORMAT
from viewer_bridge.translators.tree_viewer import TreeViewerServer
from viewer_bridge.transports.base import Received

try:
    from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS
except ImportError:  # a checkout from before lcmcodec.codecs, which bench/compare.py runs this script on
    from viewer_bridge.lcmcodec import VIEWER2_COMMS  # type: ignore[attr-defined,no-redef]


def payloads(points: int = 100_000, ranges: int = 10_000) -> dict[str, bytes]:
    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(points, 3)).round(6).tolist()
    colors = rng.uniform(size=(points, 3)).round(4).tolist()
    cloud = {"type": "pointcloud", "points": xyz, "channels": {"rgb": colors}}
    lidar_ranges = rng.uniform(0.1, 30.0, size=ranges).round(4).tolist()
    lidar = {"type": "planar_lidar", "ranges": lidar_ranges, "angle_start": -3.14159, "angle_step": 0.000628}
    return {
        f"pointcloud, {points:,} points + rgb": json.dumps(
            {"timestamp": 1, "setgeometry": [{"path": ["cloud"], "geometry": cloud}]}
        ).encode(),
        f"planar_lidar, {ranges:,} ranges": json.dumps(
            {"timestamp": 1, "setgeometry": [{"path": ["lidar"], "geometry": lidar}]}
        ).encode(),
    }


def cases(
    points: int = 100_000, ranges: int = 10_000
) -> list[tuple[str, bytes, bytes, Callable[[], object]]]:
    """(label, JSON, markers, the server's path for it) per request, each sent once first from a
    client (a tree) of its own."""
    server = TreeViewerServer({}, reply=lambda channel, data: None)
    found = []
    for index, (label, data) in enumerate(payloads(points, ranges).items()):
        channel = f"DIRECTOR_TREE_VIEWER_REQUEST_<bench{index}>"
        message = VIEWER2_COMMS.message_class(
            utime=1,
            format=FORMAT,
            format_version_major=1,
            format_version_minor=0,
            num_bytes=len(data),
            data=data,
        )
        raw = VIEWER2_COMMS.encode(message)
        ((_, markers),) = server.translate(Received(channel, raw))
        ours = lambda raw=raw: server.translate(Received("DIRECTOR_TREE_VIEWER_REQUEST_<bench>", raw))  # noqa: E731
        found.append((label, data, markers, ours))
    return found


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Each big request through the server, beside `json.loads` of its JSON alone (reported)."""
    points, ranges = size.pick(full=(100_000, 10_000), quick=(100_000, 10_000), smoke=(100, 10))
    budget = size.pick(full=1.0, quick=0.3, smoke=0.0)
    rows = []
    for label, data, _, ours in cases(points, ranges):
        baseline = seconds_per_call(lambda data=data: json.loads(data), budget)
        rows.append(Measure(f"tree viewer setgeometry, {label} ({len(data):,} bytes of JSON) -> MarkerArray CDR, "
                            "the whole server path, vs json.loads of its JSON", seconds_per_call(ours, budget) * 1e3,
                            baseline * 1e3, "ms", "none (reported)", None))  # fmt: skip
    return rows


def main() -> None:
    print(f"{'request':<36} {'bytes':>10} | {'json.loads':>10} | {'bridge -> markers':>17} | {'ratio':>5}")
    for label, data, markers, ours_call in cases():
        baseline = seconds_per_call(lambda data=data: json.loads(data), 1.0)
        ours = seconds_per_call(ours_call, 1.0)
        print(
            f"{label:<36} {len(data):>10} | {baseline * 1e3:>7.1f} ms | {ours * 1e3:>14.1f} ms | {ours / baseline:>4.1f}x"
        )
        print(f"{'':<36} {'':>10}   (MarkerArray CDR: {len(markers)} bytes)")


if __name__ == "__main__":
    main()
