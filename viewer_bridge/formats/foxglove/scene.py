"""A load as one `foxglove.SceneUpdate`: one SceneEntity per link, in the link's frame and
frame_locked, with a primitive per geometry by `mappings/foxglove.yaml` (meshes embedded as binary
glTF from `viewer_bridge.formats.gltf`), frames named as on ROS's /tf (`viewer_bridge.formats.ros.tf.FrameNames`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from viewer_bridge.formats.gltf import write_gltf
from viewer_bridge.formats.mappings import FormatTables
from viewer_bridge.model.lowering import triangle_mesh
from viewer_bridge.model.scene import Geometry, Line, Link, Pose, Scene, Shape, Triad
from viewer_bridge.model.skipped import per_geometry


def scene_update(scene: Scene, frames: Callable[[str], str], stamp: tuple[int, int] = (0, 0)) -> Any:
    """The scene as a SceneUpdate: an entity per link with geometry to draw, in its link's frame."""
    table = TABLES["primitive"]
    update = SceneUpdate()

    def primitives(_: int, geometry: Geometry) -> Any:
        """The geometry's primitives in an entity of their own: merged once all are made."""
        part = SceneEntity()
        for rule, shape, pose in table.expand(geometry.shape, geometry.pose):
            primitive = getattr(part, rule.type_code).add()
            _set_pose(primitive.pose, pose)
            _set_fields(primitive, rule.values(shape))
            _set_color(primitive, geometry.color)
        return part

    for link in scene.links:
        parts = per_geometry(link, primitives)
        if not parts:
            continue
        entity = update.entities.add(id=link.name, frame_id=frames(link.name), frame_locked=True)
        entity.timestamp.seconds, entity.timestamp.nanos = stamp
        for part in parts:
            entity.MergeFrom(part)
    return update


def _set_pose(target: Any, pose: Pose) -> None:
    target.position.x, target.position.y, target.position.z = pose.position
    orientation = target.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = pose.quaternion_xyzw


def _set_fields(primitive: Any, values: dict[str, Any]) -> None:
    for name, value in values.items():
        if primitive.DESCRIPTOR.fields_by_name[name].is_repeated:  # points, colors: one dict each
            field = getattr(primitive, name)
            for item in value:
                field.add(**item)
        elif isinstance(value, list):  # a Vector3
            target = getattr(primitive, name)
            target.x, target.y, target.z = value
        else:
            setattr(primitive, name, value)


def _set_color(primitive: Any, rgba: tuple[float, float, float, float]) -> None:
    color = primitive.color
    color.r, color.g, color.b, color.a = rgba


def _glb_model(shape: Shape) -> dict[str, Any]:
    """The shape as an embedded binary glTF, its scale applied to the vertices, in the geometry's
    colour (Drake's colour is the geometry's, whatever the file's materials say)."""
    single = Scene((Link("mesh", 0, (Geometry(triangle_mesh(shape)),)),))
    data = write_gltf(single, binary=True)
    return {"data": data, "media_type": "model/gltf-binary", "scale": [1.0, 1.0, 1.0], "override_color": True}


def _triad_lines(shape: Shape) -> dict[str, Any]:
    """Three axes as a LINE_LIST from the origin, red x, green y, blue z (as meldis draws them)."""
    assert isinstance(shape, Triad)
    points, colors = [], []
    for axis in range(3):
        end = [0.0, 0.0, 0.0]
        end[axis] = shape.scale
        rgb = [0.0, 0.0, 0.0]
        rgb[axis] = 1.0
        for point in ([0.0, 0.0, 0.0], end):
            points.append({"x": point[0], "y": point[1], "z": point[2]})
            colors.append({"r": rgb[0], "g": rgb[1], "b": rgb[2], "a": 1.0})
    thickness = shape.tube if shape.tube > 0 else 0.01
    return {"type": LinePrimitive.LINE_LIST, "thickness": thickness, "points": points, "colors": colors}


def _polyline(shape: Shape) -> dict[str, Any]:
    assert isinstance(shape, Line)
    kind = LinePrimitive.LINE_LOOP if shape.closed else LinePrimitive.LINE_STRIP
    points = [{"x": x, "y": y, "z": z} for x, y, z in np.asarray(shape.points, dtype=np.float64).tolist()]
    return {"type": kind, "thickness": 2 * shape.radius if shape.radius > 0 else 0.01, "points": points}


TABLES = FormatTables(
    "foxglove", {"glb_model": _glb_model, "triad_lines": _triad_lines, "polyline": _polyline}
)
