"""Point clouds and DRAKE_DRAW_FRAMES end to end: pydrake's PointCloudToLcm, the bridge as a process
(built-in config), rclpy on the other side, and back from rclpy to Drake's own lcmt_point_cloud."""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest

from tests.conftest import lcm_url
from tests.formats.drake.test_point_cloud import pydrake_publisher
from tests.peers import BridgeProcess, RosProbe
from tests.test_router import LcmRecorder
from viewer_bridge.config.bridge import destination_name, load_config

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

POINTS = 500
# sensor_msgs/PointField datatypes, as sensor_msgs_py.point_cloud2 maps them to numpy.
ROS_DATATYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


@pytest.fixture
def probe() -> Any:
    node = RosProbe()
    yield node
    node.close()


def drake_cloud(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """N x 3 float32 points and N x 3 uint8 colours."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-2, 2, (POINTS, 3)).astype(np.float32), rng.integers(
        0, 256, (POINTS, 3), dtype=np.uint8
    )


def publish_with_pydrake(url: str, channel: str, xyz: np.ndarray, rgb: np.ndarray, time_s: float) -> Any:
    """A diagram of PointCloudToLcm and LcmPublisherSystem (C++ serializer); returns a publish()."""
    from pydrake.lcm import DrakeLcm
    from pydrake.perception import BaseField, Fields, PointCloud

    cloud = PointCloud(len(xyz), Fields(BaseField.kXYZs | BaseField.kRGBs))
    cloud.mutable_xyzs()[:] = xyz.T
    cloud.mutable_rgbs()[:] = rgb.T
    return pydrake_publisher(DrakeLcm(url), channel, cloud, "camera_optical", time_s)


def read_point_cloud2(message: Any) -> tuple[np.ndarray, np.ndarray]:
    """(N x 3 xyz, N x 3 rgb) of an rclpy PointCloud2, as sensor_msgs_py's read_points would give
    them: a structured dtype from the fields, the PCL rgb word unpacked as 0x00RRGGBB."""
    assert not message.is_bigendian
    names = [field.name for field in message.fields]
    formats = [
        "<u4" if field.name == "rgb" else "<" + ROS_DATATYPES[field.datatype] for field in message.fields
    ]
    dtype = np.dtype(
        {
            "names": names,
            "formats": formats,
            "offsets": [field.offset for field in message.fields],
            "itemsize": message.point_step,
        }
    )
    table = np.frombuffer(bytes(message.data), dtype=dtype, count=message.width * message.height)
    xyz = np.stack([table["x"], table["y"], table["z"]], axis=1)
    word = table["rgb"]
    rgb = np.stack([(word >> 16) & 0xFF, (word >> 8) & 0xFF, word & 0xFF], axis=1).astype(np.uint8)
    return xyz, rgb


def test_default_routes_name_the_topics_as_the_viewer_routes_do() -> None:
    routes = {route.name: route for route in load_config(None).routes}
    for channel, topic in [
        ("DRAKE_POINT_CLOUD", "drake/point_cloud"),
        ("DRAKE_POINT_CLOUD_CAMERA", "drake/point_cloud/camera"),
    ]:
        match = re.fullmatch(routes["point_cloud"].source.name, channel)
        assert match is not None and destination_name(routes["point_cloud"].destination.name, match) == topic
    match = re.fullmatch(routes["draw_frames"].source.name, "DRAKE_DRAW_FRAMES")
    assert (
        match is not None
        and destination_name(routes["draw_frames"].destination.name, match) == "drake/draw_frames"
    )


def test_pydrake_cloud_and_frames_reach_rclpy(probe: RosProbe, tmp_path: Path) -> None:
    from viewer_bridge.transports.lcm import LcmBus

    url = lcm_url(18)
    xyz, rgb = drake_cloud(1)
    publish = publish_with_pydrake(url, "DRAKE_POINT_CLOUD_CAMERA", xyz, rgb, time_s=1.25)
    clouds = probe.subscribe(
        "/drake/point_cloud/camera", "sensor_msgs/msg/PointCloud2", depth=1, latched=True
    )
    frames = probe.subscribe("/drake/draw_frames", "visualization_msgs/msg/MarkerArray", latched=True)
    draw = drake_lcmtypes.lcmt_viewer_draw()
    draw.timestamp, draw.num_links = 2000, 2
    draw.link_name, draw.robot_num = ["plant::gripper::tcp", "target"], [2, 0]
    draw.position = [[0.5, 0.0, 0.25], [1.0, -1.0, 0.0]]
    draw.quaternion = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]  # the second turned 180 deg about z
    bus = LcmBus(url)
    bridge = BridgeProcess("--lcm-url", url, "--set", "time=sim")  # the cloud stamped with its utime
    try:
        bridge.wait_for_line(" running (")

        def sent() -> bool:
            publish()
            bus.publish("DRAKE_DRAW_FRAMES", draw.encode())
            return bool(clouds) and bool(frames)

        assert probe.wait_for(sent, timeout=30), bridge.lines
    finally:
        assert bridge.stop() == 0
        bus.close()
    message = clouds[-1]
    assert (message.height, message.width) == (1, POINTS)
    assert (message.point_step, message.row_step, message.is_dense) == (16, 16 * POINTS, True)
    assert [(f.name, f.offset, f.datatype, f.count) for f in message.fields] == [
        ("x", 0, 7, 1),
        ("y", 4, 7, 1),
        ("z", 8, 7, 1),
        ("rgb", 12, 7, 1),
    ]
    assert message.header.frame_id == "camera_optical"
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (1, 250_000_000)
    got_xyz, got_rgb = read_point_cloud2(message)
    np.testing.assert_array_equal(got_xyz, xyz)
    np.testing.assert_array_equal(got_rgb, rgb)

    markers = [marker for marker in frames[-1].markers if marker.action == 0]
    assert sorted(marker.ns for marker in markers) == ["plant/gripper/tcp", "target"]
    for marker in markers:
        assert marker.type == 5 and marker.header.frame_id == "world"  # LINE_LIST
        row = 0 if marker.ns == "target" else 1
        assert [marker.pose.position.x, marker.pose.position.y] == [[1.0, 0.5][row], [-1.0, 0.0][row]]
        ends = [(p.x, p.y, p.z) for p in marker.points[1::2]]  # x, y, z axis tips, 0.25 m (meldis)
        assert ends == [(0.25, 0.0, 0.0), (0.0, 0.25, 0.0), (0.0, 0.0, 0.25)]
        assert [(c.r, c.g, c.b) for c in marker.colors[::2]] == [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    target = next(marker for marker in markers if marker.ns == "target")
    assert abs(target.pose.orientation.w) < 1e-9 and abs(target.pose.orientation.z) == 1.0


def test_rclpy_cloud_reaches_drake_as_lcmt_point_cloud(probe: RosProbe, tmp_path: Path) -> None:
    from sensor_msgs.msg import PointCloud2, PointField

    url = lcm_url(19)
    xyz, rgb = drake_cloud(2)
    with_hole = xyz.copy()
    with_hole[7] = np.nan  # a depth camera's "no return": left out, as Drake's PointCloudToLcm does
    table = np.zeros(POINTS, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<u4")])
    table["x"], table["y"], table["z"] = with_hole.T
    table["rgb"] = (rgb[:, 0].astype(np.uint32) << 16) | (rgb[:, 1].astype(np.uint32) << 8) | rgb[:, 2]
    message = PointCloud2()
    message.header.frame_id = "camera_link"
    message.header.stamp.sec, message.header.stamp.nanosec = 3, 500_000_000
    message.height, message.width = 1, POINTS
    message.fields = [
        PointField(name=name, offset=4 * index, datatype=PointField.FLOAT32, count=1)
        for index, name in enumerate(("x", "y", "z", "rgb"))
    ]
    message.point_step, message.row_step, message.is_dense = 16, 16 * POINTS, False
    message.data = table.tobytes()
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--lcm-url", url)
    publisher = probe.publisher("/drake_in/point_cloud", "sensor_msgs/msg/PointCloud2")
    try:
        bridge.wait_for_line(" running (")
        received = lambda: recorder.messages.get("DRAKE_POINT_CLOUD_FROM_ROS")  # noqa: E731
        deadline = time.monotonic() + 60
        while not received() and time.monotonic() < deadline:  # until discovery has matched the two
            publisher.publish(message)
            time.sleep(0.2)
    finally:
        assert bridge.stop() == 0
        recorder.close()
    arrived = received()
    assert arrived, f"no lcmt_point_cloud arrived; bridge log:\n{bridge.lines}"
    cloud = drake_lcmtypes.lcmt_point_cloud.decode(arrived[0])  # Drake's own class reads it
    assert cloud.utime == 3_500_000 and cloud.frame_name == "camera_link"
    assert cloud.flags == drake_lcmtypes.lcmt_point_cloud.IS_STRICTLY_FINITE
    assert [(f.name, f.byte_offset, f.datatype, f.count) for f in cloud.fields] == [
        ("x", 0, 7, 1),
        ("y", 4, 7, 1),
        ("z", 8, 7, 1),
        ("rgb", 12, 6, 1),
    ]
    kept = np.ones(POINTS, dtype=bool)
    kept[7] = False
    assert (cloud.width, cloud.height, cloud.point_step) == (POINTS - 1, 1, 16)
    # Read as meldis reads it: N x num_fields float32, the rgb column's bytes r, g, b, 0.
    raw = np.frombuffer(cloud.data, dtype=np.float32).reshape(-1, cloud.num_fields)
    np.testing.assert_array_equal(raw[:, :3], xyz[kept])
    np.testing.assert_array_equal(
        raw[:, 3].astype(np.float32).view(np.uint8).reshape(-1, 4)[:, :3], rgb[kept]
    )
