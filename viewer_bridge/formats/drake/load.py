"""Drake's `lcmt_viewer_load_robot` to and from the scene model (reading first, then writing).

The load message carries the geometry of every link. How Drake fills a geometry (see
docs/PROTOCOLS.md section 1): the type code chooses the shape, and `float_data` holds its
parameters, with two traps: a cylinder or capsule is [radius, length] (radius first), and a MESH
is one of three things told apart by `string_data`: a file path, an in-memory mesh as JSON, or
(when empty) a mesh array [V, T, 3V vertex floats, 3T index floats]. A HalfSpace arrives as a
50 x 50 x 1 box shifted half a metre down; it cannot be told from a box. `TABLES` binds
mappings/drake.yaml to the encoders it names.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError, ShapeDataError
from viewer_bridge.formats.mappings import FormatTables
from viewer_bridge.lcmcodec.codecs import GEOMETRY_DATA, LINK_DATA, LOAD_ROBOT
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.lcmcodec.serde import LcmMessage
from viewer_bridge.model.scene import (
    FileContents,
    Geometry,
    InMemoryMesh,
    Link,
    MeshFile,
    Pose,
    Scene,
    Shape,
    TriangleMesh,
    Vector3,
)
from viewer_bridge.model.skipped import per_geometry


def _geometry_code(name: str) -> int:
    return int(GEOMETRY_DATA.constant(name))


# The geometry type codes, as the schema (lcmtypes/lcmt_viewer_geometry_data.lcm) declares them.
BOX, SPHERE, CYLINDER, MESH, CAPSULE, ELLIPSOID = map(
    _geometry_code, ("BOX", "SPHERE", "CYLINDER", "MESH", "CAPSULE", "ELLIPSOID")
)
_LOAD_TYPE = LOAD_ROBOT.type_name


def _mesh(data: Sequence[float], text: str) -> Shape:
    if not text:
        return _triangle_mesh(data)
    scale = _scale(data)
    if text.lstrip().startswith("{"):
        return _in_memory_mesh(text, scale)
    return MeshFile(text, scale)


def _scale(data: Sequence[float]) -> Vector3:
    if len(data) >= 3:
        return (float(data[0]), float(data[1]), float(data[2]))
    if len(data) == 1:  # uniform scale, as older Drake versions sent it
        return (float(data[0]), float(data[0]), float(data[0]))
    return (1.0, 1.0, 1.0)


def _triangle_mesh(data: Sequence[float]) -> TriangleMesh:
    if len(data) < 2:
        raise ShapeDataError(f"mesh array needs V and T, got {len(data)} floats", len(data))
    vertex_count, triangle_count = data[0], data[1]
    for index, count in enumerate((vertex_count, triangle_count)):
        if count < 0 or count != int(count):
            raise ShapeDataError(f"mesh array count {count} is not a whole number >= 0", index)
    v, t = int(vertex_count), int(triangle_count)
    expected = 2 + 3 * v + 3 * t
    if len(data) != expected:
        raise ShapeDataError(
            f"mesh array with V={v}, T={t} needs {expected} floats, got {len(data)}", len(data)
        )
    values = np.asarray(data, dtype=np.float64)
    vertices = values[2 : 2 + 3 * v].reshape(v, 3)
    index_floats = values[2 + 3 * v :]
    invalid = (index_floats < 0) | (index_floats >= v) | (index_floats != np.floor(index_floats))
    if invalid.any():
        bad = int(np.flatnonzero(invalid)[0])
        raise ShapeDataError(
            f"mesh array index {index_floats[bad]} is not a vertex index below V={v}", 2 + 3 * v + bad
        )
    return TriangleMesh(vertices, index_floats.astype(np.int64).reshape(t, 3))


def _json_error(reason: str, position: int = 0) -> ShapeDataError:
    """An error in the in-memory-mesh JSON of `string_data`, at a character position."""
    return ShapeDataError(reason, position, "character", "string_data")


def _in_memory_mesh(text: str, scale: Vector3) -> InMemoryMesh:
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise _json_error(f"in-memory mesh JSON: {error.msg}", error.pos) from None
    root = _json_object(document, "in_memory_mesh", "the document")
    mesh_file = _file_contents(_json_object(root, "mesh_file", "in_memory_mesh"), "mesh_file")
    supporting: dict[str, FileContents | str] = {}
    files = root.get("supporting_files", {})
    if not isinstance(files, dict):
        raise _json_error("in-memory mesh: supporting_files is not an object")
    for name, entry in files.items():
        if isinstance(entry, dict) and isinstance(entry.get("path"), str) and "contents" not in entry:
            supporting[name] = entry["path"]
        elif isinstance(entry, dict):
            supporting[name] = _file_contents(entry, f"supporting_files.{name}")
        else:
            raise _json_error(f"in-memory mesh: supporting file {name!r} is not an object")
    return InMemoryMesh(mesh_file, supporting, scale)


def _json_object(parent: Any, key: str, where: str) -> dict[str, Any]:
    value = parent.get(key) if isinstance(parent, dict) else None
    if not isinstance(value, dict):
        raise _json_error(f"in-memory mesh: {where} has no object {key!r}")
    return value


def _file_contents(entry: dict[str, Any], where: str) -> FileContents:
    contents, extension = entry.get("contents"), entry.get("extension")
    hint = entry.get("filename_hint", "")
    if not isinstance(contents, str) or not isinstance(extension, str) or not isinstance(hint, str):
        raise _json_error(f"in-memory mesh: {where} needs string 'contents' and 'extension'")
    try:
        data = base64.b64decode(contents, validate=True)
    except ValueError as error:  # binascii.Error, or non-ASCII text
        raise _json_error(f"in-memory mesh: {where}.contents is not base64 ({error})") from None
    return FileContents(data, extension, hint)


def _geometry_from_lcm(message: LcmMessage) -> Geometry:
    """One `lcmt_viewer_geometry_data` as a scene geometry (raises `ShapeDataError`)."""
    if message.type == MESH:  # three kinds of mesh, told apart by string_data: code, not table
        shape = _mesh(message.float_data, message.string_data)
    elif message.type in TABLES["geometry_data"].types.values():
        values = {"float_data": message.float_data, "string_data": message.string_data}
        try:
            shape = TABLES["geometry_data"].decode(message.type, values)
        except ValueError as error:
            raise ShapeDataError(str(error), len(message.float_data)) from None
    else:
        raise ShapeDataError(f"unknown geometry type {message.type}", 0, "element", "type")
    x, y, z = message.position
    qw, qx, qy, qz = message.quaternion
    r, g, b, a = message.color
    return Geometry(shape, Pose((x, y, z), (qw, qx, qy, qz)), (r, g, b, a))


def scene_from_load(message: LcmMessage) -> Scene:
    """A decoded `lcmt_viewer_load_robot` as a scene with no poses yet.

    Raises `DecodeError` naming `link[i].geom[j].<field>` for a geometry that makes no shape.
    """
    links = []
    for link_index, link in enumerate(message.link):
        links.append(Link(link.name, link.robot_num, _link_geometries(link, f"link[{link_index}]")))
    return Scene(tuple(links))


def link_from_lcm(message: LcmMessage) -> Link:
    """A decoded `lcmt_viewer_link_data` (e.g. from `DRAKE_VIEWER_DEFORMABLE`) as a link."""
    return Link(message.name, message.robot_num, _link_geometries(message, "", LINK_DATA.type_name))


def _link_geometries(link: LcmMessage, prefix: str, type_name: str = _LOAD_TYPE) -> tuple[Geometry, ...]:
    geometries = []
    for index, geometry in enumerate(link.geom):
        try:
            geometries.append(_geometry_from_lcm(geometry))
        except ShapeDataError as error:
            field = f"{prefix}.geom[{index}].{error.field}".lstrip(".")
            raise DecodeError(type_name, field, error.offset, error.reason, unit=error.unit) from None
    return tuple(geometries)


def decode_load(data: Buffer) -> Scene:
    """Bytes of an `lcmt_viewer_load_robot` straight to a scene."""
    return scene_from_load(LOAD_ROBOT.strict.decode(data))


def _mesh_array(shape: TriangleMesh) -> dict[str, Any]:
    counts = [float(len(shape.vertices)), float(len(shape.triangles))]
    return {
        "float_data": counts
        + shape.vertices.ravel().tolist()
        + shape.triangles.ravel().astype(float).tolist(),
        "string_data": "",
    }


def _in_memory(shape: InMemoryMesh) -> dict[str, Any]:
    return {"string_data": _in_memory_json(shape.mesh_file, shape.supporting_files)}


# The encoders the table (mappings/drake.yaml) names for what it cannot express itself.
TABLES = FormatTables("drake", {"mesh_array": _mesh_array, "in_memory_json": _in_memory})


def _in_memory_json(mesh_file: FileContents, supporting: Any) -> str:
    def contents(file: FileContents) -> dict[str, str]:
        return {
            "contents": base64.b64encode(file.contents).decode("ascii"),
            "extension": file.extension,
            "filename_hint": file.filename_hint,
        }

    root: dict[str, Any] = {"mesh_file": contents(mesh_file)}
    if supporting:
        root["supporting_files"] = {
            name: {"path": entry} if isinstance(entry, str) else contents(entry)
            for name, entry in supporting.items()
        }
    # Drake writes compact JSON with sorted keys; so do we, so that bytes survive a round trip.
    return json.dumps({"in_memory_mesh": root}, separators=(",", ":"), sort_keys=True)


def _geometry_to_lcm(geometry: Geometry) -> LcmMessage:
    """One scene geometry as Drake writes it (a half-space becomes Drake's box)."""
    ((rule, shape, pose),) = TABLES["geometry_data"].expand(geometry.shape, geometry.pose)
    fields = {"float_data": [], "string_data": ""} | rule.values(shape)
    float_data, string_data = fields["float_data"], fields["string_data"]
    return GEOMETRY_DATA.message_class(
        type=rule.type_code,
        position=list(pose.position),
        quaternion=list(pose.quaternion_wxyz),
        color=list(geometry.color),
        string_data=string_data,
        num_float_data=len(float_data),
        float_data=float_data,
    )


def _link_to_lcm(link: Link) -> LcmMessage:
    geoms = per_geometry(link, lambda _, geometry: _geometry_to_lcm(geometry))
    return LINK_DATA.message_class(name=link.name, robot_num=link.robot_num, num_geom=len(geoms), geom=geoms)


def load_from_scene(scene: Scene) -> LcmMessage:
    """The `lcmt_viewer_load_robot` that describes the scene's geometry."""
    links = [_link_to_lcm(link) for link in scene.links]
    return LOAD_ROBOT.message_class(num_links=len(links), link=links)


__all__ = [
    "TABLES",
    "decode_load",
    "link_from_lcm",
    "load_from_scene",
    "scene_from_load",
]
