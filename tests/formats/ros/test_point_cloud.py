"""ROS 2 PointCloud2 CDR: written (against rosbags and rclpy), read in any layout, and the checks on
bad input."""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
import pytest

from tests.formats.test_point_cloud import sample_cloud
from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.ros.message_types import POINT_CLOUD2
from viewer_bridge.formats.ros.messages import from_cdr, make, to_cdr
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr, cloud_to_cdr
from viewer_bridge.model.scene import StampedPointCloud


@pytest.mark.parametrize(("colors", "normals"), [(False, False), (True, False), (True, True)])
def test_point_cloud2_cdr_reads_back_in_rosbags_and_rclpy(colors: bool, normals: bool) -> None:
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import PointCloud2

    cloud = sample_cloud(colors=colors, normals=normals)
    data = cloud_to_cdr(StampedPointCloud(cloud, "", -1_500_000))  # before time 0: sec -2, nsec 5e8
    theirs = from_cdr(data, POINT_CLOUD2)
    assert theirs.header.frame_id == "world"
    assert (theirs.header.stamp.sec, theirs.header.stamp.nanosec) == (-2, 500_000_000)
    step = 12 + 4 * colors + 12 * normals
    assert (theirs.height, theirs.width, theirs.point_step, theirs.row_step) == (1, 30, step, 30 * step)
    assert theirs.is_dense and not theirs.is_bigendian
    table = np.frombuffer(theirs.data.tobytes(), dtype=np.float32).reshape(30, -1)
    np.testing.assert_array_equal(table[:, :3], cloud.points)
    if colors:
        word = table[:, 3].copy().view(np.uint32)  # PCL: 0x00RRGGBB
        rgb = np.stack([(word >> 16) & 255, (word >> 8) & 255, word & 255], axis=1)
        np.testing.assert_array_equal(rgb, np.rint(cloud.colors * 255))
    if normals:
        np.testing.assert_array_equal(table[:, -3:], cloud.normals)
    ours = deserialize_message(data, PointCloud2)
    assert [field.name for field in ours.fields] == [field.name for field in theirs.fields]
    assert bytes(ours.data) == theirs.data.tobytes()
    back = cloud_from_cdr(data)
    assert back.cloud == cloud and back.frame == "world" and back.time_us == -1_500_000


def _ros_message(fields: list[tuple[str, int, int]], rows: np.ndarray, **extra: Any) -> bytes:
    values = {
        "header": make("std_msgs/msg/Header", frame_id="cam"),
        "fields": [
            make("sensor_msgs/msg/PointField", name=name, offset=offset, datatype=datatype, count=1)
            for name, offset, datatype in fields
        ],
        "data": np.frombuffer(rows.tobytes(), dtype=np.uint8),
        **extra,
    }
    return to_cdr(make(POINT_CLOUD2, **values))


def test_an_organised_big_endian_float64_cloud_with_row_padding_and_rgba() -> None:
    """The general layout: 2 x 3 points, 8 padding bytes per row, FLOAT64 xyz, rgba, big-endian."""
    dtype = np.dtype({"names": ["x", "y", "z", "rgba"], "formats": [">f8", ">f8", ">f8", ">u4"],
                      "offsets": [0, 8, 16, 28], "itemsize": 32})  # fmt: skip
    points = np.arange(18, dtype=np.float64).reshape(6, 3)
    points[4] = np.nan  # left out
    rows = np.zeros(6, dtype=dtype)
    rows["x"], rows["y"], rows["z"] = points.T
    rows["rgba"] = 0xFF000000 | (np.arange(6) * 40 << 16) | (7 << 8) | 9
    padded = np.zeros((2, 3 * 32 + 8), dtype=np.uint8)
    padded[:, : 3 * 32] = np.frombuffer(rows.tobytes(), dtype=np.uint8).reshape(2, 96)
    fields = [("x", 0, 8), ("y", 8, 8), ("z", 16, 8), ("rgba", 28, 6)]
    data = _ros_message(fields, padded, height=2, width=3, point_step=32, row_step=104, is_bigendian=True)
    stamped = cloud_from_cdr(data)
    kept = [0, 1, 2, 3, 5]
    np.testing.assert_array_equal(stamped.cloud.points, points[kept])
    expected = np.stack([np.arange(6) * 40, np.full(6, 7), np.full(6, 9)], axis=1)[kept] / 255.0
    np.testing.assert_array_equal(stamped.cloud.colors, expected)
    assert stamped.frame == "cam"


def test_point_cloud2_with_a_claimed_count_too_large_is_refused_before_allocating() -> None:
    data = bytearray(cloud_to_cdr(StampedPointCloud(sample_cloud(3), "cam", 0)))
    fields_count_at = 4 + 8 + 4 + len(b"cam\0")  # after the stamp and the frame_id, then height, width
    fields_count_at += 8
    assert struct.unpack_from("<I", data, fields_count_at)[0] == 4
    data[fields_count_at : fields_count_at + 4] = struct.pack("<I", 2**31)
    with pytest.raises(DecodeError, match="count 2147483648") as caught:
        cloud_from_cdr(bytes(data))
    assert caught.value.field == "fields" and caught.value.type_name == POINT_CLOUD2


@pytest.mark.parametrize(
    ("cut", "field"),
    [(2, ""), (10, "header.stamp.nanosec"), (30, "fields"), (-20, "data"), (-1, "is_dense")],
)
def test_truncated_point_cloud2_names_the_field(cut: int, field: str) -> None:
    data = cloud_to_cdr(StampedPointCloud(sample_cloud(3), "cam", 0))
    with pytest.raises(DecodeError) as caught:
        cloud_from_cdr(data[:cut])
    assert caught.value.field == field


def test_an_empty_point_cloud2_is_an_empty_cloud() -> None:
    stamped = cloud_from_cdr(to_cdr(make(POINT_CLOUD2)))
    assert len(stamped.cloud) == 0 and stamped.cloud.points.shape == (0, 3)
