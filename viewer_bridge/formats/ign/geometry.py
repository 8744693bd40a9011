"""Scene shapes to and from ign/gz `Geometry` messages, as the table in `mappings/ign.yaml` says.

`TABLES` binds that table to the encoders it names: ign-msgs 8 has no inline triangle mesh, so
a mesh array travels as a MESH whose filename is a `data:` URI holding an OBJ, and an in-memory
mesh file as one holding the file; a line as the repeated `points`. Reading a `Geometry` back
parses those URIs again (`shape_from_geometry`).
"""

from __future__ import annotations

import base64
import re
from typing import Any

import numpy as np

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.formats.mappings import FormatTables, ShapeRule
from viewer_bridge.model.scene import FileContents, InMemoryMesh, Line, Shape, TriangleMesh


def _data_uri_obj(shape: TriangleMesh) -> dict[str, Any]:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in shape.vertices.tolist()]
    lines += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in shape.triangles.tolist()]
    text = "\n".join(lines) + "\n"
    return {"mesh.filename": "data:model/obj;base64," + base64.b64encode(text.encode()).decode("ascii")}


def _data_uri_file(shape: InMemoryMesh) -> dict[str, Any]:
    file = shape.mesh_file
    media = f"model/{file.extension.lstrip('.')};name={file.filename_hint}"
    return {"mesh.filename": f"data:{media};base64," + base64.b64encode(file.contents).decode("ascii")}


def _polyline_points(shape: Line) -> dict[str, Any]:
    return {"points": shape.path().tolist()}


TABLES = FormatTables(
    "ign",
    {"obj_data_uri": _data_uri_obj, "file_data_uri": _data_uri_file, "polyline_points": _polyline_points},
)


def _set_field(message: Any, path: str, value: Any) -> None:
    *parents, last = path.split(".")
    for name in parents:
        message = getattr(message, name)
    target: Any = getattr(message, last) if isinstance(value, list) else None
    if hasattr(target, "add"):  # a repeated Vector3d: one per point
        for point in value:
            item = target.add()
            item.x, item.y, item.z = point
    elif isinstance(value, list):  # a vector: Vector3d or Vector2d
        for axis, component in zip("xyz", value, strict=False):
            setattr(target, axis, component)
    else:
        setattr(message, last, value)


def _get_field(message: Any, path: str, rule: ShapeRule) -> Any:
    *parents, last = path.split(".")
    for name in parents:
        message = getattr(message, name)
    value = getattr(message, last)
    if path in rule.list_fields:
        return [getattr(value, axis) for axis in "xyz"[: len(rule.fields[path])]]
    return value


def geometry_message(shape: Shape) -> Any:
    """One shape as a `Geometry` (a half-space becomes a PLANE; see mappings/ign.yaml)."""
    message = MESSAGES.Geometry()
    fill_geometry(message, shape)
    return message


def fill_geometry(message: Any, shape: Shape) -> None:
    """Write the shape into a `Geometry` message (a Visual's, or one of its own): type and fields."""
    ((rule, _, _),) = TABLES["geometry"].expand(shape)  # a SceneError for a shape ign cannot hold
    message.type = rule.type_code
    for path, value in rule.values(shape).items():
        _set_field(message, path, value)


def shape_from_geometry(message: Any) -> Shape:
    """A `Geometry` back as a scene shape; raises `SceneError` for one the bridge cannot read."""
    table = TABLES["geometry"]
    filename = message.mesh.filename if message.type == table.types["MESH"] else ""
    if filename.startswith("data:"):
        return _shape_from_data_uri(filename, message)
    candidates = [rule for rule in table.rules.values() if rule.type_code == message.type and rule.invertible]
    if not candidates:
        raise SceneError(f"Geometry type {table.type_name(message.type)} has no scene shape")
    rule = candidates[0]
    try:
        return rule.shape_from({path: _get_field(message, path, rule) for path in rule.fields})
    except ValueError as error:
        raise SceneError(f"Geometry: {error}") from None


_DATA_URI = re.compile(
    r"^data:model/(?P<extension>[^;,]+)(?:;name=(?P<name>[^;,]*))?;base64,(?P<data>.*)$", re.S
)


def _shape_from_data_uri(uri: str, message: Any) -> Shape:
    match = _DATA_URI.match(uri)
    if match is None:
        raise SceneError("Geometry: mesh.filename is a data: URI the bridge does not write")
    try:
        data = base64.b64decode(match["data"], validate=True)
    except ValueError as error:
        raise SceneError(f"Geometry: mesh.filename data is not base64 ({error})") from None
    if match["name"] is None:
        return _parse_obj(data.decode("utf-8", errors="replace"))
    scale = message.mesh.scale
    file = FileContents(data, "." + match["extension"], match["name"])
    return InMemoryMesh(file, {}, (scale.x, scale.y, scale.z))


def _parse_obj(text: str) -> TriangleMesh:
    """The `v` and `f` lines of an OBJ as written by `_data_uri_obj` (three values each)."""
    vertices, faces = [], []
    for number, line in enumerate(text.splitlines(), 1):
        kind, *values = line.split() or [""]
        if kind not in ("v", "f"):
            continue
        try:
            if len(values) < 3:
                raise ValueError(f"needs 3 values, has {len(values)}")
            if kind == "v":
                vertices.append([float(value) for value in values[:3]])
            else:
                faces.append([int(value.split("/")[0]) - 1 for value in values[:3]])
        except ValueError as error:
            raise SceneError(f"Geometry: mesh array OBJ line {number}: {error}") from None
    vertex_array = np.array(vertices, dtype=np.float64).reshape(-1, 3)
    face_array = np.array(faces, dtype=np.int64).reshape(-1, 3)
    if not np.isfinite(vertex_array).all():
        raise SceneError("Geometry: mesh array OBJ has a vertex that is not finite")
    if face_array.size and (face_array.min() < 0 or face_array.max() >= len(vertex_array)):
        raise SceneError("Geometry: mesh array OBJ refers to a vertex it does not have")
    return TriangleMesh(vertex_array, face_array)
