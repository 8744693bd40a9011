"""The neutral scene model every format converts to and from.

A scene is a list of links, each with geometries posed in the link frame, plus the links' poses
in the world at one instant. Shapes are plain frozen dataclasses with SI units and the natural
parameters (radius, not diameter; full box lengths; ellipsoid semi-axes). Quaternions are stored
w-first, as Drake and the tree viewer write them; formats that name x, y, z, w convert at their
edge. Poses of many links are kept as arrays so that a frame of 10,000 links stays cheap.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from viewer_bridge.errors import SceneError
from viewer_bridge.model.pose_math import (
    FloatArray as FloatArray,  # the model's array types, defined below it
)
from viewer_bridge.model.pose_math import IntArray as IntArray
from viewer_bridge.model.pose_math import (
    quaternion_product,
    rotation_matrix,
    unit_quaternions,
    wxyz_from_xyzw,
)

Rgba = tuple[float, float, float, float]
Vector3 = tuple[float, float, float]

WHITE: Rgba = (1.0, 1.0, 1.0, 1.0)


def frame_name(link_name: str) -> str:
    """A ROS/gz frame name for a Drake link name (`plant::iiwa::link_0` -> `plant/iiwa/link_0`)."""
    return link_name.replace("::", "/")


@dataclass(frozen=True, slots=True)
class Pose:
    """A rigid transform: translation (x, y, z) and unit quaternion (w, x, y, z)."""

    position: Vector3 = (0.0, 0.0, 0.0)
    quaternion_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    @property
    def quaternion_xyzw(self) -> tuple[float, float, float, float]:
        """The same rotation in the x, y, z, w order of ROS and gz messages."""
        w, x, y, z = self.quaternion_wxyz
        return (x, y, z, w)

    def matrix(self) -> FloatArray:
        """The 4x4 homogeneous matrix of this pose."""
        result = np.eye(4)
        result[:3, :3] = rotation_matrix(np.asarray(self.quaternion_wxyz, dtype=np.float64))
        result[:3, 3] = self.position
        return result

    def compose(self, other: Pose) -> Pose:
        """`self * other`: `other` expressed in the frame that `self` is expressed in."""
        # Plain floats: for one pose this is many times faster than numpy on 3-vectors.
        w, x, y, z = self.quaternion_wxyz
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / norm, x / norm, y / norm, z / norm
        px, py, pz = other.position
        # v + 2w (u x v) + 2 u x (u x v), with u = (x, y, z): the rotated child position.
        cx, cy, cz = 2 * (y * pz - z * py), 2 * (z * px - x * pz), 2 * (x * py - y * px)
        rotated = (
            px + w * cx + (y * cz - z * cy),
            py + w * cy + (z * cx - x * cz),
            pz + w * cz + (x * cy - y * cx),
        )
        sx, sy, sz = self.position
        position = (sx + rotated[0], sy + rotated[1], sz + rotated[2])
        return Pose(position, quaternion_product(self.quaternion_wxyz, other.quaternion_wxyz))


def _vector3(values: Sequence[float] | FloatArray) -> Vector3:
    return (float(values[0]), float(values[1]), float(values[2]))


def pose_from_xyzw(position: Sequence[float], xyzw: Sequence[float], what: str) -> Pose:
    """A pose from a ROS/gz message's position and x, y, z, w quaternion, checked.

    Raises `SceneError` naming `what` for a non-finite position or a quaternion that is not a
    rotation (see `unit_quaternions`).
    """
    if not np.isfinite(position).all():
        raise SceneError(f"{what}.position is not finite")
    w, x, y, z = wxyz_from_xyzw(unit_quaternions([xyzw], what))[0].tolist()
    return Pose(_vector3(position), (w, x, y, z))


def link_poses_from_xyzw(
    timestamp_ms: int,
    names: Sequence[str],
    robot_nums: Sequence[int] | None,
    positions: npt.ArrayLike,
    xyzw: npt.ArrayLike,
    what: str,
) -> LinkPoses:
    """Link poses from N positions and N x, y, z, w quaternions (a PoseArray, a Pose_V), checked.

    Raises `SceneError` when the counts differ, or naming the first row of `what` whose position
    is not finite or whose quaternion is not a rotation.
    """
    position_array = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    count = len(position_array)
    if len(names) != count:
        raise SceneError(f"{what} has {count} poses but {len(names)} link names were given")
    finite = np.isfinite(position_array).all(axis=1)
    if not finite.all():
        raise SceneError(f"{what}[{int(np.flatnonzero(~finite)[0])}].position is not finite")
    quaternions = wxyz_from_xyzw(unit_quaternions(np.asarray(xyzw).reshape(count, 4), what))
    numbers = (
        np.zeros(count, dtype=np.int32) if robot_nums is None else np.asarray(robot_nums, dtype=np.int32)
    )
    return LinkPoses(int(timestamp_ms), tuple(names), numbers, position_array, quaternions)


# --- shapes ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Box:
    size: Vector3  # full lengths along x, y, z


@dataclass(frozen=True, slots=True)
class Sphere:
    radius: float


@dataclass(frozen=True, slots=True)
class Cylinder:
    radius: float
    length: float  # along the shape's z axis


@dataclass(frozen=True, slots=True)
class Capsule:
    radius: float
    length: float  # of the cylindrical part, caps excluded


@dataclass(frozen=True, slots=True)
class Ellipsoid:
    radii: Vector3  # semi-axes a, b, c along x, y, z


@dataclass(frozen=True, slots=True)
class HalfSpace:
    """Everything below the z = 0 plane of the geometry frame (outward normal +z)."""


@dataclass(frozen=True, slots=True)
class MeshFile:
    """A mesh stored in a file the receiver must be able to read (.obj, .gltf, .vtk, ...)."""

    path: str
    scale: Vector3 = (1.0, 1.0, 1.0)


@dataclass(frozen=True, eq=False, slots=True)
class TriangleMesh:
    """Vertices (V x 3) and triangles (T x 3 vertex indices) carried in the message itself.

    `colors` (V x 3 RGB in [0, 1], optional) colours each vertex (a contact surface's pressure);
    targets that cannot colour vertices use the geometry's colour.
    """

    vertices: FloatArray
    triangles: IntArray
    colors: FloatArray | None = None

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TriangleMesh):
            return NotImplemented
        return bool(
            np.array_equal(self.vertices, other.vertices) and np.array_equal(self.triangles, other.triangles)
        )


@dataclass(frozen=True, slots=True)
class FileContents:
    """A file's bytes in memory, with the extension that says how to read them."""

    contents: bytes
    extension: str
    filename_hint: str = ""


@dataclass(frozen=True, slots=True)
class InMemoryMesh:
    """A mesh file carried in memory, with the files it refers to (textures, .mtl, .bin)."""

    mesh_file: FileContents
    supporting_files: Mapping[str, FileContents | str] = field(default_factory=dict)
    scale: Vector3 = (1.0, 1.0, 1.0)  # a `str` supporting file is a path on the sender's disk


@dataclass(frozen=True, eq=False, slots=True)
class PointCloud:
    """Points (N x 3), with optional per-point colours (N x 3 RGB in [0, 1]), normals (N x 3)
    and named channels.

    Director's `pointcloud` and `planar_lidar` (ranges turned into points), Drake's
    `lcmt_point_cloud` and ROS's `PointCloud2` all read as this. Checked when made: every array
    N x 3 and finite, colours in [0, 1], else `SceneError` naming the array and its first bad row.
    """

    points: FloatArray
    colors: FloatArray | None = None
    channels: Mapping[str, Sequence[Any]] = field(default_factory=dict)
    normals: FloatArray | None = None

    def __post_init__(self) -> None:
        count = _check_rows(self.points, "points", None)
        if self.colors is not None:
            _check_rows(self.colors, "colors", count)
            if count and (self.colors.min() < 0.0 or self.colors.max() > 1.0):
                outside = (self.colors < 0.0) | (self.colors > 1.0)
                row = int(np.flatnonzero(outside.any(axis=1))[0])
                raise SceneError(f"point cloud colors[{row}] is outside [0, 1]")
        if self.normals is not None:
            _check_rows(self.normals, "normals", count)

    def __len__(self) -> int:
        return len(self.points)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PointCloud):
            return NotImplemented
        return bool(
            np.array_equal(self.points, other.points)
            and _same_optional(self.colors, other.colors)
            and _same_optional(self.normals, other.normals)
            and self.channels == other.channels
        )


def _check_rows(values: npt.NDArray[Any], what: str, count: int | None) -> int:
    """The row count of an N x 3 finite array; `SceneError` naming `what` otherwise."""
    if values.ndim != 2 or values.shape[1] != 3 or (count is not None and len(values) != count):
        wanted = "N x 3" if count is None else f"{count} x 3 (one row per point)"
        raise SceneError(f"point cloud {what} must be {wanted}, got shape {values.shape}")
    if not np.isfinite(values).all():  # flat first: many times faster than per row on N x 3
        row = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
        raise SceneError(f"point cloud {what}[{row}] is not finite")
    return len(values)


def _same_optional(a: FloatArray | None, b: FloatArray | None) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return bool(np.array_equal(a, b))


@dataclass(frozen=True, slots=True)
class StampedPointCloud:
    """A point cloud as a sensor sends it: the frame its points are expressed in, and when.

    `time_us` is microseconds (Drake's `utime`); `frame` a ROS-style name (`::` already `/`).
    """

    cloud: PointCloud
    frame: str
    time_us: int


@dataclass(frozen=True, slots=True)
class Triad:
    """X, Y and Z axes of length `scale`, drawn red, green and blue; `tube` for thick axes."""

    scale: float = 1.0
    tube: bool = False


@dataclass(frozen=True, eq=False, slots=True)
class Line:
    """A polyline through N >= 2 points, optionally closed, a tube when `radius` > 0, with arrowheads."""

    points: FloatArray
    radius: float = 0.01
    closed: bool = False
    start_head: bool = False
    end_head: bool = False
    head_radius: float = 0.05
    head_length: float = 0.05

    def path(self) -> FloatArray:
        """The points to draw through: the first again at the end when the line is closed."""
        return np.concatenate((self.points, self.points[:1])) if self.closed else self.points

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Line):
            return NotImplemented
        flags = (self.radius, self.closed, self.start_head, self.end_head, self.head_radius, self.head_length)
        other_flags = (
            other.radius,
            other.closed,
            other.start_head,
            other.end_head,
            other.head_radius,
            other.head_length,
        )
        return bool(np.array_equal(self.points, other.points) and flags == other_flags)


Shape = (
    Box
    | Sphere
    | Cylinder
    | Capsule
    | Ellipsoid
    | HalfSpace
    | MeshFile
    | TriangleMesh
    | InMemoryMesh
    | PointCloud
    | Triad
    | Line
)

# The names the translation tables in mappings/ use for the shapes.
SHAPE_KINDS: dict[str, type[Shape]] = {
    "box": Box,
    "sphere": Sphere,
    "cylinder": Cylinder,
    "capsule": Capsule,
    "ellipsoid": Ellipsoid,
    "half_space": HalfSpace,
    "mesh_file": MeshFile,
    "triangle_mesh": TriangleMesh,
    "in_memory_mesh": InMemoryMesh,
    "point_cloud": PointCloud,
    "triad": Triad,
    "line": Line,
}
_KIND_OF: dict[type[Shape], str] = {shape_type: kind for kind, shape_type in SHAPE_KINDS.items()}


def shape_kind(shape: Shape) -> str:
    """The table name of a shape's kind, e.g. "cylinder"."""
    return _KIND_OF[type(shape)]


@dataclass(frozen=True, slots=True)
class Geometry:
    """A shape placed in its link's frame, with an RGBA colour in [0, 1]."""

    shape: Shape
    pose: Pose = Pose()
    color: Rgba = WHITE


@dataclass(frozen=True, slots=True)
class Link:
    """A rigid body: its Drake name, model instance number and geometries."""

    name: str
    robot_num: int = 0
    geometries: tuple[Geometry, ...] = ()

    @property
    def frame(self) -> str:
        return frame_name(self.name)


@dataclass(frozen=True, eq=False, slots=True)
class LinkPoses:
    """Every link's pose at one instant, as arrays (one row per link).

    `positions` is N x 3, `quaternions_wxyz` N x 4; `robot_nums` N. The arrays may be read-only
    views into a received buffer, or shared by every route that reads one decoded draw (float32
    from `DrawDecoder`): copy before changing them.
    """

    timestamp_ms: int
    names: tuple[str, ...]
    robot_nums: npt.NDArray[np.int32]
    positions: FloatArray
    quaternions_wxyz: FloatArray
    _rows: dict[str, int] | None = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def of_arrays(
        cls,
        timestamp_ms: int,
        names: tuple[str, ...],
        robot_nums: npt.NDArray[np.int32],
        positions: FloatArray,
        quaternions_wxyz: FloatArray,
    ) -> LinkPoses:
        """The same as `LinkPoses(...)` at about half the cost, for a decoder making one a frame.

        The frozen dataclass's `__init__` stores each field through `object.__setattr__`; this
        stores straight into the slots.
        """
        poses = object.__new__(cls)
        _SET_TIMESTAMP(poses, timestamp_ms)
        _SET_NAMES(poses, names)
        _SET_ROBOT_NUMS(poses, robot_nums)
        _SET_POSITIONS(poses, positions)
        _SET_QUATERNIONS(poses, quaternions_wxyz)
        _SET_ROWS(poses, None)
        return poses

    def __len__(self) -> int:
        return len(self.names)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LinkPoses):
            return NotImplemented
        return bool(
            self.timestamp_ms == other.timestamp_ms
            and self.names == other.names
            and np.array_equal(self.robot_nums, other.robot_nums)
            and np.array_equal(self.positions, other.positions)
            and np.array_equal(self.quaternions_wxyz, other.quaternions_wxyz)
        )

    def pose(self, index: int) -> Pose:
        q = self.quaternions_wxyz[index]
        return Pose(_vector3(self.positions[index]), (float(q[0]), float(q[1]), float(q[2]), float(q[3])))

    def pose_of(self, name: str) -> Pose | None:
        row = self.row_of(name)
        return None if row is None else self.pose(row)

    def row_of(self, name: str) -> int | None:
        """The row of link `name`, or None; the name index is built on first use."""
        if self._rows is None:
            object.__setattr__(self, "_rows", {link: row for row, link in enumerate(self.names)})
        assert self._rows is not None
        return self._rows.get(name)


# The slot setters `LinkPoses.of_arrays` uses, one per field (tests check none is missing).
_SET_TIMESTAMP, _SET_NAMES, _SET_ROBOT_NUMS, _SET_POSITIONS, _SET_QUATERNIONS, _SET_ROWS = (
    LinkPoses.__dict__[name].__set__
    for name in ("timestamp_ms", "names", "robot_nums", "positions", "quaternions_wxyz", "_rows")
)


@dataclass(frozen=True, slots=True)
class Scene:
    """The geometry of every link, and (once a frame has arrived) where each link is."""

    links: tuple[Link, ...] = ()
    poses: LinkPoses | None = None

    def with_poses(self, poses: LinkPoses) -> Scene:
        return Scene(self.links, poses)

    def link_pose(self, link: Link) -> Pose:
        """The link's world pose; links absent from the frame (e.g. `world`) sit at identity."""
        if self.poses is None:
            return Pose()
        return self.poses.pose_of(link.name) or Pose()

    def geometry_count(self) -> int:
        return sum(len(link.geometries) for link in self.links)


__all__ = [
    "Box",
    "Capsule",
    "Cylinder",
    "Ellipsoid",
    "FileContents",
    "FloatArray",
    "Geometry",
    "HalfSpace",
    "InMemoryMesh",
    "IntArray",
    "Line",
    "Link",
    "LinkPoses",
    "MeshFile",
    "PointCloud",
    "Pose",
    "Rgba",
    "SHAPE_KINDS",
    "Scene",
    "Shape",
    "Sphere",
    "StampedPointCloud",
    "Triad",
    "TriangleMesh",
    "Vector3",
    "WHITE",
    "frame_name",
    "shape_kind",
]
