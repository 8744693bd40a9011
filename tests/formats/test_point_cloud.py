"""Point clouds across formats: the scene model's checks, and clouds from Drake through ROS and
back (Drake's lcmt_point_cloud itself: tests/formats/drake/test_point_cloud.py; ROS's
PointCloud2: tests/formats/ros/test_point_cloud.py)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.optional import peer
from viewer_bridge.errors import SceneError
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm, cloud_to_lcm
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr, cloud_to_cdr
from viewer_bridge.model.scene import PointCloud, StampedPointCloud

# Drake's own lcm-gen classes, shipped with pydrake: imported by the tests that use them
drake_lcmtypes = peer("drake")


def sample_cloud(count: int = 30, colors: bool = True, normals: bool = False, seed: int = 3) -> PointCloud:
    rng = np.random.default_rng(seed)
    points = rng.uniform(-5, 5, (count, 3)).astype(np.float32).astype(np.float64)  # float32 on the wire
    normal_rows = rng.normal(size=(count, 3)).astype(np.float32).astype(np.float64)
    return PointCloud(
        points,
        rng.integers(0, 256, (count, 3)) / 255.0 if colors else None,
        normals=normal_rows if normals else None,
    )


# --- the scene model's checks -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"points": np.zeros((2, 2))}, r"points must be N x 3, got shape \(2, 2\)"),
        ({"points": np.array([[0, 0, 0], [np.inf, 0, 0]])}, r"points\[1\] is not finite"),
        ({"colors": np.array([[0, 0, 0], [0, 2, 0]])}, r"colors\[1\] is outside \[0, 1\]"),
        ({"colors": np.zeros((3, 3))}, r"colors must be 2 x 3 \(one row per point\)"),
        ({"normals": np.array([[np.nan, 0, 1], [0, 0, 1]])}, r"normals\[0\] is not finite"),
    ],
)
def test_point_cloud_checks_its_arrays(kwargs: dict[str, Any], message: str) -> None:
    values = {"points": np.zeros((2, 3)), **kwargs}
    with pytest.raises(SceneError, match=message):
        PointCloud(**values)


@pytest.mark.parametrize("count", [0, 1, 2, 257])
@pytest.mark.parametrize(("colors", "normals"), [(False, False), (True, False), (False, True), (True, True)])
def test_clouds_survive_drake_to_ros_to_drake(count: int, colors: bool, normals: bool) -> None:
    cloud = sample_cloud(count, colors=colors, normals=normals, seed=count)
    stamped = StampedPointCloud(cloud, "plant/camera", 123_456_000)
    via_ros = cloud_from_cdr(cloud_to_cdr(cloud_from_lcm(cloud_to_lcm(stamped))))
    assert via_ros.cloud == cloud  # colours and normals kept, even for an empty cloud
    assert (via_ros.frame, via_ros.time_us) == ("plant/camera", 123_456_000)
    theirs = drake_lcmtypes.lcmt_point_cloud.decode(cloud_to_lcm(via_ros))
    assert theirs.width == count and theirs.point_step == 12 + 4 * colors + 12 * normals
