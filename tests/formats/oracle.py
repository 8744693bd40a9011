"""Independent expectations for the translator tests, computed from Drake's raw messages.

The oracle reads `lcmt_viewer_geometry_data` fields by index (as docs/PROTOCOLS.md describes them) and
composes poses with pydrake's own RigidTransform, so it shares no code with the translators.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from viewer_bridge.lcmcodec.serde import LcmMessage

BOX, SPHERE, CYLINDER, MESH, CAPSULE, ELLIPSOID = 1, 2, 3, 4, 5, 6
F32 = 1e-6  # float32 round-off, relative


def close(actual: Any, expected: Any) -> bool:
    """Equal within float32 round-off (Drake sends float32; the targets carry float64)."""
    actual, expected = np.asarray(actual, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    return actual.shape == expected.shape and bool(np.allclose(actual, expected, rtol=F32, atol=1e-7))


def transform(position: Any, quaternion_wxyz: Any) -> Any:
    """pydrake's RigidTransform (pydrake imported here: a core-only run skips the tests that need it)."""
    eigen_geometry, drake_math = (
        pytest.importorskip("pydrake.common.eigen_geometry"),
        pytest.importorskip("pydrake.math"),
    )
    w, x, y, z = (float(value) for value in quaternion_wxyz)
    return drake_math.RigidTransform(
        eigen_geometry.Quaternion(w, x, y, z), np.asarray(position, dtype=np.float64)
    )


def world_pose(link_position: Any, link_wxyz: Any, geometry: LcmMessage) -> tuple[np.ndarray, np.ndarray]:
    """(position, quaternion x y z w) of a geometry in the world, composed by Drake."""
    pose = transform(link_position, link_wxyz) @ transform(geometry.position, geometry.quaternion)
    q = pose.rotation().ToQuaternion()
    xyzw = np.array([q.x(), q.y(), q.z(), q.w()])
    return pose.translation(), xyzw if xyzw[3] >= 0 else -xyzw  # q and -q are the same rotation


def same_rotation(xyzw_a: Any, xyzw_b: Any, tolerance: float = 1e-5) -> bool:
    a, b = np.asarray(xyzw_a, dtype=np.float64), np.asarray(xyzw_b, dtype=np.float64)
    return bool(min(np.abs(a - b).max(), np.abs(a + b).max()) < tolerance)


def xyzw_of(wxyz: Any) -> list[float]:
    """A w-first quaternion (Drake's order) in ROS/gz order."""
    w, x, y, z = wxyz
    return [x, y, z, w]


def xyzw(geometry: LcmMessage) -> list[float]:
    """The geometry quaternion in ROS/gz order, straight from Drake's w-first array."""
    w, x, y, z = geometry.quaternion
    return [x, y, z, w]


def mesh_kind(geometry: LcmMessage) -> str:
    if geometry.type != MESH:
        return ""
    if not geometry.string_data:
        return "array"
    return "memory" if geometry.string_data.startswith("{") else "file"


def mesh_array(geometry: LcmMessage) -> tuple[np.ndarray, np.ndarray]:
    data = geometry.float_data
    v, t = int(data[0]), int(data[1])
    vertices = np.asarray(data[2 : 2 + 3 * v]).reshape(v, 3)
    return vertices, np.asarray(data[2 + 3 * v :], dtype=np.int64).reshape(t, 3)
