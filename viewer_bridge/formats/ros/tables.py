"""`mappings/ros.yaml` bound to the functions that write what its tables cannot express: `TABLES`.

The `shape` table's `mesh` (a `shape_msgs/Mesh`'s triangles and vertices as N x 3 arrays),
and the `marker` table's mesh resources, TRIANGLE_LIST, POINTS, the triad's LINE_LIST and lines
(an arrow becomes ARROW). Each returns the values its rule adds to the message or marker.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.mappings import FormatTables
from viewer_bridge.model.scene import InMemoryMesh, Line, MeshFile, PointCloud, Triad, TriangleMesh


def _mesh(shape: TriangleMesh, options: dict[str, Any]) -> dict[str, Any]:
    # Arrays, which the CDR writer takes for sequences of Point and MeshTriangle in one copy each.
    return {"triangles": shape.triangles, "vertices": shape.vertices}


def _mesh_resource(shape: MeshFile, options: dict[str, Any]) -> dict[str, Any]:
    if not options.get("embed_mesh_files"):
        return {"mesh_resource": f"file://{shape.path}"}
    try:
        with open(shape.path, "rb") as file:
            data = file.read()
    except OSError as error:
        raise SceneError(f"mesh file {shape.path} cannot be embedded: {error.strerror}") from None
    return _embedded(os.path.basename(shape.path), data)


def _embedded_mesh(shape: InMemoryMesh, options: dict[str, Any]) -> dict[str, Any]:
    name = shape.mesh_file.filename_hint or f"mesh{shape.mesh_file.extension}"
    return _embedded(os.path.basename(name), shape.mesh_file.contents)


def _embedded(name: str, data: bytes) -> dict[str, Any]:
    # RViz reads mesh_file.data when mesh_resource is embedded://<mesh_file.filename>.
    return {"mesh_resource": f"embedded://{name}", "mesh_file": (name, data)}


def _points(shape: PointCloud, options: dict[str, Any]) -> dict[str, Any]:
    size = float(options["point_size"])
    values: dict[str, Any] = {"points": shape.points, "scale": (size, size, 0.0)}
    if shape.colors is not None:
        values["colors"] = np.concatenate((shape.colors, np.ones((len(shape.colors), 1))), axis=1)
    return values


_TRIAD_POINTS = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 1, 0], [0, 0, 0], [0, 0, 1]], dtype=np.float64)
_TRIAD_COLORS = np.repeat(np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 0, 1, 1]], dtype=np.float64), 2, axis=0)


def _triad(shape: Triad, options: dict[str, Any]) -> dict[str, Any]:
    width = (0.05 if shape.tube else 0.01) * shape.scale
    return {"points": _TRIAD_POINTS * shape.scale, "colors": _TRIAD_COLORS, "scale": (width, 0.0, 0.0)}


_ARROW = 0  # visualization_msgs/Marker.ARROW


def _line_strip(shape: Line, options: dict[str, Any]) -> dict[str, Any]:
    width = 2 * shape.radius if shape.radius > 0 else 0.002
    if len(shape.points) == 2 and shape.end_head and not shape.start_head and not shape.closed:
        # An arrow: ARROW with points (start, end); scale = shaft and head diameters, head length.
        scale = (width, 2 * shape.head_radius, shape.head_length)
        return {"type": _ARROW, "points": shape.points, "scale": scale}
    return {"points": shape.path(), "scale": (width, 0.0, 0.0)}


def _triangle_list(shape: TriangleMesh, options: dict[str, Any]) -> dict[str, Any]:
    corners = shape.triangles.reshape(-1)
    values: dict[str, Any] = {"points": shape.vertices[corners]}
    if shape.colors is not None:  # per vertex (a contact surface's pressure), opaque
        values["colors"] = np.concatenate((shape.colors[corners], np.ones((len(corners), 1))), axis=1)
    return values


TABLES = FormatTables(
    "ros",
    {
        "mesh": _mesh,
        "mesh_resource": _mesh_resource,
        "embedded_mesh": _embedded_mesh,
        "triangle_list": _triangle_list,
        "points": _points,
        "triad": _triad,
        "line_strip": _line_strip,
    },
)
