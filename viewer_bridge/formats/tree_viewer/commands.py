"""The objects inside tree viewer commands, read and checked: a setgeometry's `geometry` as a
scene geometry, a `transform` as a pose. Errors name the command and field (`SceneError`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.tree_viewer.requests import TABLES
from viewer_bridge.model.pose_math import unit_quaternions
from viewer_bridge.model.scene import FloatArray, Geometry, Line, PointCloud, Pose, Shape, TriangleMesh


def pose_from_transform(value: Any, where: str) -> Pose:
    """A tree viewer transform (translation, w-first quaternion; both optional) as a pose."""
    if not isinstance(value, dict):
        raise SceneError(f"{where} is not an object")
    translation = _numbers(value.get("translation", [0.0, 0.0, 0.0]), 3, f"{where}.translation")
    quaternion = _numbers(value.get("quaternion", [1.0, 0.0, 0.0, 0.0]), 4, f"{where}.quaternion")
    w, x, y, z = unit_quaternions([quaternion], f"{where}.quaternion")[0].tolist()
    return Pose((translation[0], translation[1], translation[2]), (w, x, y, z))


def _numbers(value: Any, count: int, where: str) -> list[float]:
    if (
        not isinstance(value, list)
        or len(value) != count
        or not all(isinstance(item, int | float) and not isinstance(item, bool) for item in value)
        or not np.isfinite(value).all()
    ):
        raise SceneError(f"{where} must be {count} finite numbers")
    return [float(item) for item in value]


def geometry_from_command(value: Any, where: str) -> Geometry:
    """A setgeometry `geometry` object as a scene geometry (pose = its `transform`)."""
    if not isinstance(value, dict):
        raise SceneError(f"{where} is not an object")
    kind = value.get("type")
    shape = _shape(value, kind, where)
    color = _numbers(value.get("color", [1.0, 1.0, 1.0, 1.0]), 4, f"{where}.color")
    pose = pose_from_transform(value.get("transform", {}), f"{where}.transform")
    return Geometry(shape, pose, (color[0], color[1], color[2], color[3]))


def _shape(value: dict[str, Any], kind: Any, where: str) -> Shape:
    table = TABLES["geometry"]
    reader = _SHAPE_READERS.get(kind) if isinstance(kind, str) else None
    if reader is not None:
        return reader(value, where)
    if kind == "mesh_file" and isinstance(value.get("scale"), int | float):
        value = {**value, "scale": [value["scale"]] * 3}  # a number: a uniform scale
    if not isinstance(kind, str) or kind not in table.types:
        raise SceneError(f"{where}.type: unknown geometry type {kind!r}")
    try:
        return table.decode(kind, value)
    except ValueError as error:
        raise SceneError(f"{where}: {error}") from None


def _points(value: Any, where: str) -> FloatArray:
    """A list of [x, y, z] triplets as an N x 3 array of finite numbers."""
    return _finite_array(value, where, 3, "a list of [x, y, z] triplets of numbers")


def _finite_array(value: Any, where: str, width: int | None, what: str) -> FloatArray:
    """A JSON list as a float array: N numbers (`width` None) or N rows of `width`; all finite."""
    if not isinstance(value, list):
        raise SceneError(f"{where} must be {what}")
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise SceneError(f"{where} must be {what}") from None
    if array.size == 0:
        return array.reshape((0,) if width is None else (0, width))
    if array.ndim != (1 if width is None else 2) or (width is not None and array.shape[1] != width):
        raise SceneError(f"{where} must be {what}, got shape {array.shape}")
    if not np.isfinite(array).all():
        raise SceneError(f"{where} holds a value that is not finite")
    return array


def _flag(value: dict[str, Any], key: str, default: bool, where: str) -> bool:
    flag = value.get(key, default)
    if not isinstance(flag, bool):
        raise SceneError(f"{where}.{key} must be true or false")
    return flag


def _number(value: dict[str, Any], key: str, default: float | None, where: str) -> float:
    number = value.get(key, default)
    if isinstance(number, bool) or not isinstance(number, int | float) or not np.isfinite(number):
        raise SceneError(f"{where}.{key} must be a finite number")
    return float(number)


def _pointcloud_shape(value: dict[str, Any], where: str) -> PointCloud:
    points = _points(value.get("points"), f"{where}.points")
    channels = value.get("channels", {})
    if not isinstance(channels, dict):
        raise SceneError(f"{where}.channels must be an object")
    colors = None
    others: dict[str, list[Any]] = {}
    for name, values in channels.items():
        if not isinstance(values, list) or len(values) != len(points):
            raise SceneError(f"{where}.channels.{name} must be a list of {len(points)} values, one per point")
        if name == "rgb":
            colors = _points(values, f"{where}.channels.rgb")
        else:
            others[name] = values
    return PointCloud(points, colors, others)


def _planar_lidar_shape(value: dict[str, Any], where: str) -> PointCloud:
    """Ranges measured about the z axis from `angle_start` every `angle_step`, as points (z = 0)."""
    distances = _finite_array(value.get("ranges"), f"{where}.ranges", None, "a list of distances")
    start, step = _number(value, "angle_start", None, where), _number(value, "angle_step", None, where)
    with np.errstate(over="ignore", invalid="ignore"):
        angles = start + step * np.arange(len(distances))
        points = np.stack(
            (distances * np.cos(angles), distances * np.sin(angles), np.zeros(len(distances))), axis=1
        )
    if not np.isfinite(points).all():
        raise SceneError(f"{where}: ranges and angles give points that are not finite")
    return PointCloud(points)


def _line_shape(value: dict[str, Any], where: str) -> Line:
    points = _points(value.get("points"), f"{where}.points")
    if len(points) < 2:
        raise SceneError(f"{where}.points needs 2 or more points")
    head_radius = _number(value, "head_radius", 0.05, where)
    return Line(
        points,
        radius=_number(value, "radius", 0.01, where),
        closed=_flag(value, "closed", False, where),
        start_head=_flag(value, "start_head", False, where),
        end_head=_flag(value, "end_head", False, where),
        head_radius=head_radius,
        head_length=_number(value, "head_length", head_radius, where),
    )


def _mesh_shape(value: dict[str, Any], where: str) -> TriangleMesh:
    vertices = _points(value.get("vertices"), f"{where}.vertices")
    faces = _points(value.get("faces"), f"{where}.faces")  # triplets of numbers, checked below
    if faces.size and ((faces != np.floor(faces)).any() or faces.min() < 0 or faces.max() >= len(vertices)):
        raise SceneError(f"{where}.faces refer to a vertex that does not exist")
    return TriangleMesh(vertices, faces.astype(np.int64))


_SHAPE_READERS: dict[str, Callable[[dict[str, Any], str], Shape]] = {
    "mesh_data": _mesh_shape,
    "pointcloud": _pointcloud_shape,
    "planar_lidar": _planar_lidar_shape,
    "line": _line_shape,
}
