"""Lowerings: a shape rewritten as other shapes, for targets that lack it.

A table rule `{as: <name>}` names one of `LOWERINGS`. Each returns the parts that replace the
shape, each posed in the shape's own frame. Meshes are read and tessellated with trimesh, so a
mesh file a target cannot reference (shape_msgs/Mesh carries vertices) is read from disk here;
that is the only I/O in the translators, and a missing or unreadable file is a `SceneError`.
"""

from __future__ import annotations

import functools
import io
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from viewer_bridge.errors import SceneError
from viewer_bridge.model.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    FloatArray,
    HalfSpace,
    InMemoryMesh,
    Line,
    MeshFile,
    Pose,
    Shape,
    Sphere,
    TriangleMesh,
    Vector3,
)

if TYPE_CHECKING:
    import trimesh

Parts = list[tuple[Shape, Pose]]

# Drake's stand-in for an infinite half-space (geometry/drake_visualizer.cc): a 50 x 50 x 1 box
# whose top face is the plane.
HALF_SPACE_BOX: Vector3 = (50.0, 50.0, 1.0)
HALF_SPACE_OFFSET = Pose((0.0, 0.0, -0.5))

# Tessellation density: enough to look round in a viewer, small enough for a 1000-link scene.
_SECTIONS = 24
_SPHERE_SUBDIVISIONS = 2


@dataclass(frozen=True, slots=True)
class Lowering:
    function: Callable[[Any], Parts]
    produces: tuple[str, ...]  # the shape kinds the parts can be


def half_space_box(shape: HalfSpace) -> Parts:
    """A half-space as the 50 x 50 x 1 box Drake draws for it."""
    return [(Box(HALF_SPACE_BOX), HALF_SPACE_OFFSET)]


def capsule_parts(shape: Capsule) -> Parts:
    """A capsule as a cylinder and two spheres at its ends (how drake-ros draws one in RViz)."""
    half = shape.length / 2.0
    return [
        (Cylinder(shape.radius, shape.length), Pose()),
        (Sphere(shape.radius), Pose((0.0, 0.0, half))),
        (Sphere(shape.radius), Pose((0.0, 0.0, -half))),
    ]


def triangle_mesh_parts(shape: Shape) -> Parts:
    return [(triangle_mesh(shape), Pose())]


def triangle_mesh(shape: Shape) -> TriangleMesh:
    """Any shape as vertices and triangles; mesh files are read with trimesh.

    Primitives are tessellated once per set of dimensions (a load often has many equal ones):
    the arrays of a cached mesh are read-only, so that no caller can change another's.
    """
    match shape:
        case TriangleMesh():
            return shape
        case Box() | Sphere() | Ellipsoid() | Cylinder() | Capsule() | HalfSpace():
            return _primitive_mesh(shape)
        case MeshFile(path, scale):
            if not os.path.isfile(path):
                raise SceneError(f"mesh file {path} does not exist")
            return _scaled(_load(path, None, path), scale)
        case InMemoryMesh(mesh_file, _, scale):
            data = io.BytesIO(mesh_file.contents)
            return _scaled(
                _load(data, mesh_file.extension, mesh_file.filename_hint or "in-memory mesh"), scale
            )
    raise SceneError(f"no triangle mesh for {shape!r}")


@functools.lru_cache(maxsize=1024)
def _primitive_mesh(shape: Box | Sphere | Ellipsoid | Cylinder | Capsule | HalfSpace) -> TriangleMesh:
    mesh = _tessellated(shape)
    mesh.vertices.flags.writeable = False
    mesh.triangles.flags.writeable = False
    return mesh


def import_trimesh() -> None:
    """Import trimesh now, if not yet (1 to 2.5 s with scipy on a busy core, once per process).

    A translator of Drake's scenes calls this when it is made, before the route starts: imported
    on the first load instead, the load's shapes went out 1 to 2 s late (`shapes` latency p50
    1460 ms where reading and converting the demo's meshes takes about 0.1 s), and every other
    route fell behind meanwhile (a second of draws superseded) while the import held the GIL."""
    import trimesh  # noqa: F401


def _tessellated(shape: Box | Sphere | Ellipsoid | Cylinder | Capsule | HalfSpace) -> TriangleMesh:
    import trimesh  # here, not at the top: importing a converter must stay cheap (about 0.5 s with scipy)

    match shape:
        case Box(size):
            return _from_trimesh(trimesh.creation.box(extents=size))
        case Sphere(radius):
            return _from_trimesh(trimesh.creation.icosphere(_SPHERE_SUBDIVISIONS, radius))
        case Ellipsoid(radii):
            unit = trimesh.creation.icosphere(_SPHERE_SUBDIVISIONS, 1.0)
            return TriangleMesh(np.asarray(unit.vertices) * radii, np.asarray(unit.faces, dtype=np.int64))
        case Cylinder(radius, length):
            return _from_trimesh(trimesh.creation.cylinder(radius, length, sections=_SECTIONS))
        case Capsule(radius, length):
            return _from_trimesh(trimesh.creation.capsule(length, radius, count=[_SECTIONS, _SECTIONS]))
        case HalfSpace():
            box = triangle_mesh(Box(HALF_SPACE_BOX))
            return TriangleMesh(box.vertices + HALF_SPACE_OFFSET.position, box.triangles)


def _load(source: Any, extension: str | None, name: str) -> TriangleMesh:
    import trimesh

    file_type = extension.lstrip(".").lower() if extension else None
    try:
        loaded = trimesh.load(source, file_type=file_type, force="mesh", process=False)
    except Exception as error:  # trimesh raises many kinds for unreadable files
        raise SceneError(f"mesh {name} could not be read: {error}") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise SceneError(f"mesh {name} has no triangles")
    return _from_trimesh(loaded)


def _from_trimesh(mesh: trimesh.Trimesh) -> TriangleMesh:
    return TriangleMesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64))


def _scaled(mesh: TriangleMesh, scale: Vector3) -> TriangleMesh:
    return TriangleMesh(mesh.vertices * np.asarray(scale), mesh.triangles)


def arrow_mesh(line: Line) -> TriangleMesh:
    """A two-point line with an end head as a solid arrow (a shaft and a cone), for renderers that
    draw only triangles. The head never outgrows the arrow: at most half its length."""
    import trimesh

    start, end = np.asarray(line.points[0], dtype=np.float64), np.asarray(line.points[-1], dtype=np.float64)
    length = float(np.linalg.norm(end - start))
    if length == 0.0:
        raise SceneError("an arrow of zero length has no direction")
    head = min(line.head_length, length / 2)
    shaft = _from_trimesh(trimesh.creation.cylinder(line.radius, length - head, sections=_SECTIONS))
    cone = _from_trimesh(trimesh.creation.cone(line.head_radius, head, sections=_SECTIONS))
    vertices = np.concatenate(
        (shaft.vertices + (0.0, 0.0, (length - head) / 2), cone.vertices + (0.0, 0.0, length - head))
    )
    triangles = np.concatenate((shaft.triangles, cone.triangles + len(shaft.vertices)))
    # Built along +z from the origin; the columns of `basis` turn z onto the arrow's direction.
    return TriangleMesh(vertices @ _basis_along((end - start) / length).T + start, triangles)


def _basis_along(direction: FloatArray) -> FloatArray:
    """A rotation matrix whose third column is the unit vector `direction`."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, direction)
    x /= np.linalg.norm(x)
    basis: FloatArray = np.stack((x, np.cross(direction, x), direction), axis=1)
    return basis


LOWERINGS: dict[str, Lowering] = {
    "half_space_box": Lowering(half_space_box, ("box",)),
    "capsule_parts": Lowering(capsule_parts, ("cylinder", "sphere")),
    "triangle_mesh": Lowering(triangle_mesh_parts, ("triangle_mesh",)),
}
