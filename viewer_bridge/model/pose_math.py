"""Batched pose maths for the scene model: quaternion order, pose rows, unit checks, composing.

The numpy functions over many poses at once (N x 4 quaternions, N x 7 pose rows, parts fixed on
links) that the formats' fast paths use every frame; the scene model itself (`viewer_bridge.model.scene`)
keeps the types. Quaternions are w-first, as Drake writes them, except where a name says xyzw.
The quaternion order is converted here and in `scene.Pose.quaternion_xyzw`, nowhere else.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import numpy.typing as npt

from viewer_bridge.errors import SceneError

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def rotation_matrix(quaternion_wxyz: FloatArray) -> FloatArray:
    """The 3x3 rotation of a (normalised here) w-first quaternion."""
    w, x, y, z = quaternion_wxyz / np.linalg.norm(quaternion_wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_product(a: Iterable[Any], b: Iterable[Any]) -> tuple[Any, Any, Any, Any]:
    """The Hamilton product `a * b` of w-first quaternions: floats, or arrays row-wise."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


_XYZW_FROM_WXYZ = np.array([1, 2, 3, 0])  # one fancy index: cheaper than np.roll per frame
_WXYZ_FROM_XYZW = np.array([3, 0, 1, 2])


def xyzw_from_wxyz(quaternions: npt.ArrayLike) -> FloatArray:
    """N x 4 quaternions from Drake's w, x, y, z order to ROS/gz's x, y, z, w."""
    wxyz = np.asarray(quaternions)
    xyzw = np.empty(wxyz.shape, dtype=np.float64)
    _write_xyzw(xyzw, wxyz)
    return xyzw


def _write_xyzw(out: FloatArray, wxyz: npt.NDArray[Any]) -> None:
    # Two slice copies: a fancy index would build a temporary and cost several times more.
    out[..., :3] = wxyz[..., 1:]
    out[..., 3] = wxyz[..., 0]


def wxyz_from_xyzw(quaternions: npt.ArrayLike) -> FloatArray:
    """N x 4 quaternions from ROS/gz's x, y, z, w order to Drake's w, x, y, z."""
    return np.asarray(quaternions, dtype=np.float64)[..., _WXYZ_FROM_XYZW]


def pose_rows_xyzw(positions: npt.ArrayLike, quaternions_wxyz: npt.ArrayLike) -> FloatArray:
    """N poses as N x 7 rows x y z, qx qy qz qw: a ROS or gz Pose's fields in order.

    Little-endian float64, as both CDR (little-endian) and protobuf write doubles.
    """
    rows = np.empty((len(np.asarray(positions)), 7), dtype="<f8")
    write_pose_rows_xyzw(rows, positions, quaternions_wxyz)
    return rows


def write_pose_rows_xyzw(rows: FloatArray, positions: npt.ArrayLike, quaternions_wxyz: npt.ArrayLike) -> None:
    """`pose_rows_xyzw` into an N x 7 array the caller keeps (an encoder's buffer: no allocation)."""
    rows[:, :3] = positions
    _write_xyzw(rows[:, 3:], np.asarray(quaternions_wxyz))


# How far from 1 a quaternion's length may be before it is refused rather than normalised.
QUATERNION_TOLERANCE = 1e-2


def unit_quaternions(quaternions: npt.ArrayLike, what: str) -> FloatArray:
    """Normalised copies of N x 4 quaternions (either order).

    A quaternion a little off unit length (a sender that does not normalise) is normalised:
    that is the documented fallback; one within float32 round-off of 1 is kept as it is. NaN,
    infinity or a length far from one cannot be a rotation and raise `SceneError` naming the
    first bad row of `what`.
    """
    values = np.asarray(quaternions, dtype=np.float64)
    norms = np.linalg.norm(values, axis=-1)
    bad = ~np.isfinite(norms) | (np.abs(norms - 1.0) > QUATERNION_TOLERANCE)
    if bad.any():
        row = int(np.flatnonzero(np.atleast_1d(bad))[0])
        raise SceneError(
            f"{what}[{row}]: quaternion of length {np.atleast_1d(norms)[row]:.6g} is not a rotation"
        )
    # Within float32 round-off of unit length: left as sent, so values survive a round trip.
    scale = np.where(np.abs(norms - 1.0) <= 1e-6, 1.0, norms)
    normalised: FloatArray = values / scale[..., None]
    return normalised


class PartsOnLinks:
    """Parts fixed on links (e.g. markers): every part's world pose, all at once per frame.

    A part at (p, b) in its link, the link at (t, a) in the world, is at t + a (0, p) a* with
    orientation a b (Hamilton products). Both `a (0, p)` and `a b` are linear in the link's
    quaternion `a`, with a 4 x 4 matrix per part (column j is `e_j (0, p)`, `e_j b` for the
    basis quaternion e_j), worked out once at load; `u a*` is bilinear in u and a with constant
    coefficients: one matrix product with the 16 products u_j a_k. So a frame costs a gather,
    one batched matrix-vector product, one outer product and one matrix product.

    Arrays are feature-major (one contiguous row per coefficient, one column per part) so that
    every operation runs over long contiguous rows.
    """

    def __init__(self, positions: FloatArray, quaternions_wxyz: FloatArray) -> None:
        """`positions` (M x 3) and unit `quaternions_wxyz` (M x 4) of the parts in their links."""
        orientations = np.asarray(quaternions_wxyz, dtype=np.float64).reshape(-1, 4).T
        offsets = np.asarray(positions, dtype=np.float64).reshape(-1, 3).T
        pure = np.concatenate((np.zeros((1, offsets.shape[1])), offsets))  # (0, p)
        # [out, j, part]: rows 0-3 e_j (0, p) (w x y z), rows 4-7 e_j b (x y z w, as written).
        by_basis = [
            np.concatenate((_product_rows(basis, pure), _product_rows(basis, orientations)[_XYZW_FROM_WXYZ]))
            for basis in np.eye(4)
        ]
        self._linear = np.ascontiguousarray(np.stack(by_basis, axis=1))

    def __len__(self) -> int:
        return int(self._linear.shape[2])

    def world_rows(
        self, link_positions: npt.ArrayLike, link_wxyz: npt.ArrayLike, rows: IntArray
    ) -> FloatArray:
        """Each part's world pose as a row x y z, qx qy qz qw (M x 7, a transposed view).

        Part i sits on link `rows[i]` of `link_positions` (N x 3) / `link_wxyz` (N x 4); the
        row N (one past the last) is the identity, for parts on links the frame does not move.
        """
        links = np.asarray(link_positions).reshape(-1, 3)
        count = len(links)
        # One column per link: w x y z, then the position; the extra column is the identity.
        poses = np.empty((7, count + 1))
        poses[:4, :count] = np.asarray(link_wxyz).reshape(-1, 4).T
        poses[4:, :count] = links.T
        poses[:, count] = _IDENTITY_COLUMN
        on_parts = poses.take(rows, axis=1)
        a = on_parts[:4]
        linear = np.einsum("ojm,jm->om", self._linear, a)  # u = a (0, p), then a b
        products = (linear[:4, None] * a[None]).reshape(16, -1)  # u_j a_k, row 4 j + k
        # u is used up: rows 1-3 take the position, so rows 1-7 are the answer as they lie.
        np.matmul(_ROTATE, products, out=linear[1:4])  # the vector part of u a*
        linear[1:4] += on_parts[4:]
        world: FloatArray = linear[1:].T
        return world


def _product_rows(a: FloatArray, b: FloatArray) -> FloatArray:
    """The Hamilton product a b of w-first quaternions as 4 rows (a column of b per part)."""
    return np.array([np.broadcast_to(value, b.shape[1:]) for value in quaternion_product(a, b)])


def _rotation_coefficients() -> FloatArray:
    """H (3 x 16): the vector part of u a* from the products u_j a_k (at 4 j + k)."""
    basis = np.eye(4)
    conjugate = np.array([1.0, -1.0, -1.0, -1.0])
    return np.array(
        [quaternion_product(basis[j], basis[k] * conjugate)[1:] for j in range(4) for k in range(4)]
    ).T


_ROTATE = _rotation_coefficients()
_IDENTITY_COLUMN = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
