"""Benchmark: a 100,000-point coloured cloud -> sensor_msgs/PointCloud2 CDR, beside the rclpy way.

Run: .venv/bin/python bench/point_cloud.py [--points 100000] [--budget 0.5]

Ours: numpy end to end (`viewer_bridge.formats.ros.point_cloud`): one float32 table, the rgb bytes
written through a view, the CDR header by struct. Baseline: what a Python user writes: a
`PointCloud2` whose data is packed point by point with `struct.pack_into` (as sensor_msgs_py's
`create_cloud` did before it used numpy), then `rclpy.serialization.serialize_message`.
Three measurements, each checked to give the same message both ways:
  1. the scene's cloud -> PointCloud2 CDR;
  2. the route: `lcmt_point_cloud` bytes (from pydrake's PointCloudToLcm layout) -> PointCloud2
     CDR; the baseline decodes with Drake's own lcm-gen class and repacks point by point;
  3. the reverse route: PointCloud2 CDR -> `lcmt_point_cloud` bytes; the baseline deserialises
     with rclpy, unpacks point by point and encodes with Drake's class.
"""

from __future__ import annotations

import argparse
import struct
from typing import Any

import drake as drake_lcmtypes
import numpy as np
from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import seconds_per_call
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2, PointField

from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm, cloud_to_lcm
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr, cloud_to_cdr
from viewer_bridge.model.scene import PointCloud, StampedPointCloud

XYZ_RGB = struct.Struct("<fffI")  # PCL's PointXYZRGB word: 0x00RRGGBB
XYZ_RGB_DRAKE = struct.Struct("<fff4B")  # PointCloudToLcm: r, g, b, 0


def cloud(points: int) -> StampedPointCloud:
    rng = np.random.default_rng(0)
    xyz = rng.uniform(-3, 3, (points, 3)).astype(np.float32).astype(np.float64)
    return StampedPointCloud(PointCloud(xyz, rng.integers(0, 256, (points, 3)) / 255.0), "camera", 1_250_000)


def _fields(rgb_datatype: int) -> list[PointField]:
    names = ("x", "y", "z", "rgb")
    types = (PointField.FLOAT32,) * 3 + (rgb_datatype,)
    return [
        PointField(name=n, offset=4 * i, datatype=t, count=1)
        for i, (n, t) in enumerate(zip(names, types, strict=True))
    ]


def rclpy_cloud(
    rows: list[tuple[float, float, float, int, int, int]], frame: str, stamp: tuple[int, int]
) -> bytes:
    """The baseline writer: a PointCloud2 packed point by point, serialised by rclpy."""
    message = PointCloud2()
    message.header.frame_id = frame
    message.header.stamp.sec, message.header.stamp.nanosec = stamp
    message.height, message.width = 1, len(rows)
    message.fields = _fields(PointField.FLOAT32)
    message.point_step, message.row_step, message.is_dense = 16, 16 * len(rows), True
    buffer = bytearray(16 * len(rows))
    for index, (x, y, z, r, g, b) in enumerate(rows):
        XYZ_RGB.pack_into(buffer, 16 * index, x, y, z, (r << 16) | (g << 8) | b)
    message.data = bytes(buffer)
    return bytes(serialize_message(message))


def drake_to_ros_baseline(data: bytes) -> bytes:
    message = drake_lcmtypes.lcmt_point_cloud.decode(data)
    rows = [(x, y, z, r, g, b) for x, y, z, r, g, b, _ in XYZ_RGB_DRAKE.iter_unpack(message.data)]
    seconds, micros = divmod(message.utime, 1_000_000)
    return rclpy_cloud(rows, message.frame_name, (seconds, micros * 1000))


def ros_to_drake_baseline(data: bytes) -> bytes:
    incoming = deserialize_message(data, PointCloud2)
    out = bytearray(16 * incoming.width)
    for index, (x, y, z, word) in enumerate(XYZ_RGB.iter_unpack(bytes(incoming.data))):
        XYZ_RGB_DRAKE.pack_into(
            out, 16 * index, x, y, z, (word >> 16) & 255, (word >> 8) & 255, word & 255, 0
        )
    message = drake_lcmtypes.lcmt_point_cloud()
    message.utime = incoming.header.stamp.sec * 1_000_000 + incoming.header.stamp.nanosec // 1000
    message.frame_name, message.width, message.height = incoming.header.frame_id, incoming.width, 1
    message.fields = []
    for field in _fields(PointField.UINT32):
        lcm_field = drake_lcmtypes.lcmt_point_cloud_field()
        lcm_field.name, lcm_field.byte_offset, lcm_field.datatype, lcm_field.count = (
            field.name,
            field.offset,
            field.datatype,
            1,
        )
        message.fields.append(lcm_field)
    message.num_fields, message.flags = 4, drake_lcmtypes.lcmt_point_cloud.IS_STRICTLY_FINITE
    message.point_step, message.row_step = 16, len(out)
    message.filler_size, message.filler = 0, b""
    message.data_size, message.data = len(out), bytes(out)
    return bytes(message.encode())


def same_ros(a: bytes, b: bytes) -> bool:
    return bool(deserialize_message(a, PointCloud2) == deserialize_message(b, PointCloud2))


def report(title: str, ours: Any, baseline: Any, budget: float) -> None:
    fast, slow = seconds_per_call(ours, budget), seconds_per_call(baseline, budget)
    print(title)
    print(f"  viewer-bridge (numpy)                 {fast * 1e3:10.2f} ms")
    print(f"  baseline (point by point, rclpy)      {slow * 1e3:10.2f} ms")
    print(f"  ratio                                 {slow / fast:10.0f}x")


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Issue 13: a 100,000-point coloured cloud -> PointCloud2 CDR, and both routes' bytes."""
    budget = size.pick(full=0.5, quick=0.2, smoke=0.0)
    stamped = cloud(100_000)
    assert stamped.cloud.colors is not None
    rgb = np.rint(stamped.cloud.colors * 255).astype(int)
    rows = [(*xyz, *color) for xyz, color in zip(stamped.cloud.points.tolist(), rgb.tolist(), strict=True)]
    lcm = cloud_to_lcm(stamped)
    cdr = cloud_to_cdr(stamped)
    cases = [
        ("100,000-point rgb cloud -> PointCloud2 CDR", lambda: cloud_to_cdr(stamped),
         lambda: rclpy_cloud(rows, "camera", (1, 250_000_000))),
        ("lcmt_point_cloud -> PointCloud2 CDR (100,000 points)", lambda: cloud_to_cdr(cloud_from_lcm(lcm)),
         lambda: drake_to_ros_baseline(lcm)),
        ("PointCloud2 CDR -> lcmt_point_cloud (100,000 points)", lambda: cloud_to_lcm(cloud_from_cdr(cdr)),
         lambda: ros_to_drake_baseline(cdr)),
    ]  # fmt: skip
    rows_out = []
    for name, ours, baseline in cases:
        fast, slow = seconds_per_call(ours, budget), seconds_per_call(baseline, budget)
        rows_out.append(Measure(name, fast * 1e3, slow * 1e3, "ms", "faster than rclpy objects", fast < slow))
    return rows_out


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--budget", type=float, default=0.5, help="seconds per measurement")
    args = parser.parse_args()

    stamped = cloud(args.points)
    rgb = np.rint(stamped.cloud.colors * 255).astype(int) if stamped.cloud.colors is not None else None
    assert rgb is not None
    rows = [(*xyz, *color) for xyz, color in zip(stamped.cloud.points.tolist(), rgb.tolist(), strict=True)]
    scene_baseline = lambda: rclpy_cloud(rows, "camera", (1, 250_000_000))  # noqa: E731
    scene_ours = lambda: cloud_to_cdr(stamped)  # noqa: E731
    assert same_ros(scene_ours(), scene_baseline())
    report(
        f"1. scene cloud -> PointCloud2 CDR, {args.points} points with rgb",
        scene_ours,
        scene_baseline,
        args.budget,
    )

    lcm = cloud_to_lcm(stamped)  # byte for byte what PointCloudToLcm publishes for this cloud
    route_ours = lambda: cloud_to_cdr(cloud_from_lcm(lcm))  # noqa: E731
    assert same_ros(route_ours(), drake_to_ros_baseline(lcm))
    report(
        "\n2. lcmt_point_cloud bytes -> PointCloud2 CDR",
        route_ours,
        lambda: drake_to_ros_baseline(lcm),
        args.budget,
    )

    cdr = scene_ours()
    back_ours = lambda: cloud_to_lcm(cloud_from_cdr(cdr))  # noqa: E731
    assert cloud_from_lcm(back_ours()).cloud == cloud_from_lcm(ros_to_drake_baseline(cdr)).cloud
    report(
        "\n3. PointCloud2 CDR -> lcmt_point_cloud bytes",
        back_ours,
        lambda: ros_to_drake_baseline(cdr),
        args.budget,
    )


if __name__ == "__main__":
    main()
