"""A load as Rerun chunks: an entity per link, each geometry a child entity, all static.

The link `plant::iiwa::link_0` of the stream rooted at `/drake/proximity` is the entity
`/drake/proximity/plant/iiwa/link_0`, in the transform frame its `frames` name gives it (as
on ROS's /tf: `proximity/plant/iiwa/link_0`; `CoordinateFrame`). Each geometry is the child
entity `<index>` (its place in the link's geometry list) in the same frame, posed in it by
`InstancePoses3D`, drawn as the archetype `mappings/rerun.yaml` gives its shape. A draw moves
the frames (`viewer_bridge.formats.rerun.transforms`); the entities never change. Everything
is static, so a viewer that connects later still gets the scene.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.mappings import FormatTables, ShapeRule
from viewer_bridge.formats.rerun.chunks import entity_path, static_chunk
from viewer_bridge.formats.rerun.schema import Chunks
from viewer_bridge.model.scene import (
    Capsule,
    Geometry,
    InMemoryMesh,
    Line,
    MeshFile,
    PointCloud,
    Pose,
    Scene,
    Shape,
    Triad,
    TriangleMesh,
)
from viewer_bridge.model.skipped import per_geometry

# What Asset3D reads, by file extension (Rerun's MediaType names); other mesh files are skipped.
MEDIA_TYPES = {
    ".glb": rr.MediaType.GLB,
    ".gltf": rr.MediaType.GLTF,
    ".obj": rr.MediaType.OBJ,
    ".stl": rr.MediaType.STL,
}
_SOLID = frozenset({"Boxes3D", "Ellipsoids3D", "Cylinders3D", "Capsules3D"})
_ALBEDO = frozenset({"Mesh3D", "Asset3D"})  # coloured by an albedo factor, not per instance
_SCALE = "instance_scale"  # an encoder's value that goes to InstancePoses3D, not the archetype


def link_entity(root: tuple[str, ...], link_name: str) -> str:
    """The entity of a Drake link under `root`: each `::`-separated part one path part."""
    return entity_path(*root, *link_name.split("::"))


def scene_chunks(scene: Scene, root: tuple[str, ...], frames: Callable[[str], str]) -> list[Chunks]:
    """Static chunks for every link with geometry to draw, and for each of its geometries."""
    table = TABLES["archetype"]
    chunks = []
    for link in scene.links:
        path, frame = link_entity(root, link.name), rr.CoordinateFrame(frames(link.name))

        def geometry_chunks(
            index: int, geometry: Geometry, path: str = path, frame: Any = frame
        ) -> list[Chunks]:
            parts = table.expand(geometry.shape, geometry.pose)
            return [
                static_chunk(
                    f"{path}/{index}" if len(parts) == 1 else f"{path}/{index}/{part}",
                    [frame, *_archetypes(rule.type or "", _values(rule, shape), pose, geometry)],
                )
                for part, (rule, shape, pose) in enumerate(parts)
            ]

        written = per_geometry(link, geometry_chunks)
        if written:
            chunks.append(static_chunk(path, [frame]))
            chunks.extend(chunk for parts in written for chunk in parts)
    return chunks


def _archetypes(type_name: str, values: dict[str, Any], pose: Pose, geometry: Geometry) -> list[Any]:
    """The geometry's pose in its link (with a mesh's scale) and its archetype, coloured."""
    scale = values.pop(_SCALE, None)
    instance = rr.InstancePoses3D(
        translations=[pose.position],
        quaternions=[pose.quaternion_xyzw],
        scales=None if scale is None else [scale],
    )
    if type_name in _ALBEDO:
        values["albedo_factor"] = geometry.color
    elif "colors" not in values:
        values["colors"] = [geometry.color]
    if type_name in _SOLID:
        values["fill_mode"] = rr.components.FillMode.Solid
    return [instance, getattr(rr, type_name)(**values)]


def _values(rule: ShapeRule, shape: Shape) -> dict[str, Any]:
    """The archetype's arguments: the table's fields as one instance each, then the encoder's."""
    values: dict[str, Any] = {name: [value] for name, value in rule.reader(shape).items()}
    return values if rule.encode is None else values | rule.encode(shape)


def _media_type(extension: str, what: str) -> rr.MediaType:
    media_type = MEDIA_TYPES.get(extension.lower())
    if media_type is None:
        known = ", ".join(MEDIA_TYPES)
        raise SceneError(f"Rerun's Asset3D reads {known} files, not {extension or 'no extension'} ({what})")
    return media_type


def _asset_file(shape: MeshFile) -> dict[str, Any]:
    media_type = _media_type(Path(shape.path).suffix, shape.path)
    try:
        contents = Path(shape.path).read_bytes()
    except OSError as error:
        raise SceneError(f"mesh file {shape.path}: {error.strerror or error}") from error
    return {"contents": contents, "media_type": media_type, _SCALE: shape.scale}


def _asset_contents(shape: InMemoryMesh) -> dict[str, Any]:
    name = shape.mesh_file.filename_hint or "in-memory mesh"
    media_type = _media_type("." + shape.mesh_file.extension.lstrip("."), name)
    return {"contents": shape.mesh_file.contents, "media_type": media_type, _SCALE: shape.scale}


def _capsule_centre(shape: Capsule) -> dict[str, Any]:
    return {"translations": [(0.0, 0.0, -0.5 * shape.length)]}


def _mesh(shape: TriangleMesh) -> dict[str, Any]:
    values: dict[str, Any] = {"vertex_positions": shape.vertices, "triangle_indices": shape.triangles}
    if shape.colors is not None:
        values["vertex_colors"] = shape.colors
    return values


def _points(shape: PointCloud) -> dict[str, Any]:
    return {"positions": shape.points} | ({} if shape.colors is None else {"colors": shape.colors})


_AXES_COLORS = np.array([[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0]])


def _triad(shape: Triad) -> dict[str, Any]:
    return {"origins": np.zeros((3, 3)), "vectors": np.eye(3) * shape.scale, "colors": _AXES_COLORS}


def _line_strip(shape: Line) -> dict[str, Any]:
    return {"strips": [shape.path()], "radii": [shape.radius]}


TABLES = FormatTables(
    "rerun",
    {
        "asset_file": _asset_file,
        "asset_contents": _asset_contents,
        "capsule_centre": _capsule_centre,
        "mesh": _mesh,
        "points": _points,
        "triad": _triad,
        "line_strip": _line_strip,
    },
)
