"""Benchmark: big tree viewer requests through viewer-bridge's server, beside `json.loads`.

Run: .venv/bin/python bench/tree_viewer.py

A setgeometry with a 100,000-point pointcloud (with an rgb channel) and one with a
10,000-range planar_lidar, each as the envelope bytes a client publishes. Ours: the whole
server path (envelope decode, JSON parse, checks, the tree, the reply, the MarkerArray CDR with
POINTS). Baseline in the same process: the standard library's `json.loads` of the same JSON.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from draw_codec import seconds_per_call  # noqa: E402

from viewer_bridge.formats.tree_viewer.envelope import FORMAT  # noqa: E402
from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS  # noqa: E402
from viewer_bridge.translators.tree_viewer import TreeViewerServer  # noqa: E402
from viewer_bridge.transports.base import Received  # noqa: E402


def payloads() -> dict[str, bytes]:
    rng = np.random.default_rng(0)
    points = rng.normal(size=(100_000, 3)).round(6).tolist()
    colors = rng.uniform(size=(100_000, 3)).round(4).tolist()
    cloud = {"type": "pointcloud", "points": points, "channels": {"rgb": colors}}
    ranges = rng.uniform(0.1, 30.0, size=10_000).round(4).tolist()
    lidar = {"type": "planar_lidar", "ranges": ranges, "angle_start": -3.14159, "angle_step": 0.000628}
    return {
        "pointcloud, 100,000 points + rgb": json.dumps(
            {"timestamp": 1, "setgeometry": [{"path": ["cloud"], "geometry": cloud}]}
        ).encode(),
        "planar_lidar, 10,000 ranges": json.dumps(
            {"timestamp": 1, "setgeometry": [{"path": ["lidar"], "geometry": lidar}]}
        ).encode(),
    }


def main() -> None:
    server = TreeViewerServer({}, reply=lambda channel, data: None)
    print(f"{'request':<36} {'bytes':>10} | {'json.loads':>10} | {'bridge -> markers':>17} | {'ratio':>5}")
    for index, (label, data) in enumerate(payloads().items()):
        channel = f"DIRECTOR_TREE_VIEWER_REQUEST_<bench{index}>"  # a client (a tree) per request
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
        baseline = seconds_per_call(lambda data=data: json.loads(data), 1.0)
        ours = seconds_per_call(
            lambda raw=raw: server.translate(Received("DIRECTOR_TREE_VIEWER_REQUEST_<bench>", raw)), 1.0
        )
        print(
            f"{label:<36} {len(data):>10} | {baseline * 1e3:>7.1f} ms | {ours * 1e3:>14.1f} ms | {ours / baseline:>4.1f}x"
        )
        print(f"{'':<36} {'':>10}   (MarkerArray CDR: {len(markers)} bytes)")


if __name__ == "__main__":
    main()
