"""A scene's geometries as ROS 2 shape_msgs CDR (`SolidPrimitive`, `Mesh`, `Plane`), and a
shape_msgs message back as a scene shape.

Which shape becomes which message, with which fields, is the `shape` table of `mappings/ros.yaml`;
`shapes_cdr` writes the bytes from the table's values and the mesh arrays (the generated writer).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.mappings import ShapeRule
from viewer_bridge.formats.ros.message_types import MESH, PLANE, SOLID_PRIMITIVE, TypedCdr
from viewer_bridge.formats.ros.tables import TABLES
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.scene import Geometry, Scene, Shape, TriangleMesh
from viewer_bridge.model.skipped import per_geometry


def shapes_cdr(scene: Scene) -> list[TypedCdr]:
    """Every geometry of the scene as shape_msgs CDR: (type name, bytes) per message, written
    from the table's values and the mesh arrays (no message objects).

    A geometry that cannot be written (a mesh file that cannot be read) is skipped alone.
    """
    table = TABLES["shape"]
    out = []
    # By id, holding the shape so that its id stays its own: lowered primitives share one
    # cached mesh, written once.
    written: dict[int, tuple[Shape, bytes]] = {}

    def messages(_: int, geometry: Geometry) -> list[TypedCdr]:
        parts = []
        for rule, shape in table.expand_unposed(geometry.shape):
            typename = rule.message or table.target
            if typename != MESH:
                data = _shape_cdr(rule, shape, typename)
            elif id(shape) in written:
                data = written[id(shape)][1]
            else:
                data = _shape_cdr(rule, shape, typename)
                written[id(shape)] = (shape, data)
            parts.append(TypedCdr(typename, data))
        return parts

    for link in scene.links:
        for parts in per_geometry(link, messages):
            out += parts
    return out


def _shape_cdr(rule: ShapeRule, shape: Shape, typename: str) -> bytes:
    """One shape's message, written from its rule's values (the table's fields, the mesh arrays)."""
    values = rule.values(shape, {})
    if rule.type_code is not None:
        values["type"] = rule.type_code
    return ros_writer(typename).write_fields(values)


def shape_from_message(message: Any) -> Shape:
    """A `SolidPrimitive`, `Mesh` or `Plane` (rosbags message) back as a scene shape."""
    if message.__msgtype__ == MESH:
        vertices = np.array([[p.x, p.y, p.z] for p in message.vertices], dtype=np.float64).reshape(-1, 3)
        triangles = np.array([t.vertex_indices for t in message.triangles], dtype=np.int64).reshape(-1, 3)
        if triangles.size and triangles.max() >= len(vertices):
            raise SceneError(f"{MESH}: a triangle refers to vertex {int(triangles.max())} of {len(vertices)}")
        return TriangleMesh(vertices, triangles)
    table = TABLES["shape"]
    if message.__msgtype__ == PLANE:
        return _decoded(lambda: table.decode_message(PLANE, {"coef": list(message.coef)}), PLANE)
    return _decoded(
        lambda: table.decode(int(message.type), {"dimensions": list(message.dimensions)}), SOLID_PRIMITIVE
    )


def _decoded(decode: Callable[[], Shape], typename: str) -> Shape:
    try:
        return decode()
    except ValueError as error:
        raise SceneError(f"{typename}: {error}") from None


__all__ = [
    "shape_from_message",
    "shapes_cdr",
]
