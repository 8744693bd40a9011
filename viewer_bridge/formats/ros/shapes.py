"""A scene's geometries as ROS 2 shape_msgs CDR (`SolidPrimitive`, `Mesh`, `Plane`), and a
shape_msgs message back as a scene shape.

Which shape becomes which message, with which fields, is the `shape` table of `mappings/ros.yaml`;
`shapes_cdr` writes the bytes straight from the table's values and the mesh arrays.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numpy as np

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.mappings import ShapeRule
from viewer_bridge.formats.ros.cdr import CDR_LE, U32, CdrWriter
from viewer_bridge.formats.ros.message_types import MESH, PLANE, SOLID_PRIMITIVE, TypedCdr
from viewer_bridge.formats.ros.tables import TABLES
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
        for rule, shape, _pose in table.expand(geometry.shape, geometry.pose):
            typename = rule.message or table.target
            if typename != MESH:
                data = _SHAPE_WRITERS[typename](rule, shape)
            elif id(shape) in written:
                data = written[id(shape)][1]
            else:
                data = _mesh_cdr(rule, shape)
                written[id(shape)] = (shape, data)
            parts.append(TypedCdr(typename, data))
        return parts

    for link in scene.links:
        for parts in per_geometry(link, messages):
            out += parts
    return out


_TYPE_AND_COUNT = struct.Struct("<B3xI")


def _solid_primitive_cdr(rule: ShapeRule, shape: Shape) -> bytes:
    """type (uint8), dimensions (float64[<=3], 8-aligned after its count), polygon (no points)."""
    dimensions = rule.values(shape)["dimensions"]
    count = len(dimensions)
    return b"".join(
        (
            CDR_LE,
            _TYPE_AND_COUNT.pack(rule.type_code, count),
            struct.pack(f"<{count}d", *dimensions),
            U32.pack(0),
        )
    )


def _plane_cdr(rule: ShapeRule, shape: Shape) -> bytes:
    return CDR_LE + struct.pack("<4d", *rule.values(shape)["coef"])


def _mesh_cdr(rule: ShapeRule, shape: Shape) -> bytes:
    """triangles (uint32 count, 3 uint32 each), vertices (uint32 count, 8-aligned, 3 float64 each)."""
    assert isinstance(shape, TriangleMesh)
    writer = CdrWriter()
    writer.pack(U32, len(shape.triangles))
    writer.add(np.ascontiguousarray(shape.triangles, dtype="<u4").tobytes())
    writer.pack(U32, len(shape.vertices))
    if len(shape.vertices):
        writer.align(8)
        writer.add(np.ascontiguousarray(shape.vertices, dtype="<f8").tobytes())
    return writer.getvalue()


_SHAPE_WRITERS: dict[str, Callable[[ShapeRule, Shape], bytes]] = {
    SOLID_PRIMITIVE: _solid_primitive_cdr,
    PLANE: _plane_cdr,
    MESH: _mesh_cdr,
}


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
