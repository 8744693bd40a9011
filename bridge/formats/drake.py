"""Drake's LCM viewer messages to and from the scene model.

`lcmt_viewer_load_robot` carries the geometry of every link; `lcmt_viewer_draw` every link's pose.
How Drake fills a geometry (see docs/PROTOCOLS.md section 1): the type code chooses the shape, and
`float_data` holds its parameters, with two traps: a cylinder or capsule is [radius, length]
(radius first), and a MESH is one of three things told apart by `string_data`: a file path, an
in-memory mesh as JSON, or (when empty) a mesh array [V, T, 3V vertex floats, 3T index floats].
A HalfSpace arrives as a 50 x 50 x 1 box shifted half a metre down; it cannot be told from a box.

The draw message also has a fast path, `DrawDecoder`, that returns numpy views into the buffer.
"""

from __future__ import annotations

import base64
import json
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from bridge.errors import DecodeError, EncodeError
from bridge.lcmcodec import DRAW, GEOMETRY_DATA, LINK_DATA, LOAD_ROBOT, Buffer, LcmMessage
from bridge.mappings import FormatTables
from bridge.scene import (
    FileContents,
    Geometry,
    InMemoryMesh,
    Link,
    LinkPoses,
    MeshFile,
    Pose,
    Scene,
    Shape,
    TriangleMesh,
    Vector3,
)
from bridge.skipped import per_geometry


def _geometry_code(name: str) -> int:
    return int(GEOMETRY_DATA.constant(name))


# The geometry type codes, as the schema (lcmtypes/lcmt_viewer_geometry_data.lcm) declares them.
BOX, SPHERE, CYLINDER, MESH, CAPSULE, ELLIPSOID = map(
    _geometry_code, ("BOX", "SPHERE", "CYLINDER", "MESH", "CAPSULE", "ELLIPSOID")
)
_LOAD_TYPE = LOAD_ROBOT.type_name


class _ShapeDataError(Exception):
    """Raised inside shape parsing; turned into a DecodeError with the field path outside."""

    def __init__(
        self, reason: str, offset: int = 0, unit: str = "element", field: str = "float_data"
    ) -> None:
        super().__init__(reason)
        self.reason = reason
        self.offset = offset
        self.unit = unit
        self.field = field


# --- load_robot -> scene -------------------------------------------------------------------------


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
        raise _ShapeDataError(f"mesh array needs V and T, got {len(data)} floats", len(data))
    vertex_count, triangle_count = data[0], data[1]
    for index, count in enumerate((vertex_count, triangle_count)):
        if count < 0 or count != int(count):
            raise _ShapeDataError(f"mesh array count {count} is not a whole number >= 0", index)
    v, t = int(vertex_count), int(triangle_count)
    expected = 2 + 3 * v + 3 * t
    if len(data) != expected:
        raise _ShapeDataError(
            f"mesh array with V={v}, T={t} needs {expected} floats, got {len(data)}", len(data)
        )
    values = np.asarray(data, dtype=np.float64)
    vertices = values[2 : 2 + 3 * v].reshape(v, 3)
    index_floats = values[2 + 3 * v :]
    invalid = (index_floats < 0) | (index_floats >= v) | (index_floats != np.floor(index_floats))
    if invalid.any():
        bad = int(np.flatnonzero(invalid)[0])
        raise _ShapeDataError(
            f"mesh array index {index_floats[bad]} is not a vertex index below V={v}", 2 + 3 * v + bad
        )
    return TriangleMesh(vertices, index_floats.astype(np.int64).reshape(t, 3))


def _json_error(reason: str, position: int = 0) -> _ShapeDataError:
    """An error in the in-memory-mesh JSON of `string_data`, at a character position."""
    return _ShapeDataError(reason, position, "character", "string_data")


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


def geometry_from_lcm(message: LcmMessage) -> Geometry:
    """One `lcmt_viewer_geometry_data` as a scene geometry (raises `_ShapeDataError`)."""
    if message.type == MESH:  # three kinds of mesh, told apart by string_data: code, not table
        shape = _mesh(message.float_data, message.string_data)
    elif message.type in TABLES["geometry_data"].types.values():
        values = {"float_data": message.float_data, "string_data": message.string_data}
        try:
            shape = TABLES["geometry_data"].decode(message.type, values)
        except ValueError as error:
            raise _ShapeDataError(str(error), len(message.float_data)) from None
    else:
        raise _ShapeDataError(f"unknown geometry type {message.type}", 0, "element", "type")
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
            geometries.append(geometry_from_lcm(geometry))
        except _ShapeDataError as error:
            field = f"{prefix}.geom[{index}].{error.field}".lstrip(".")
            raise DecodeError(type_name, field, error.offset, error.reason, unit=error.unit) from None
    return tuple(geometries)


def decode_load(data: Buffer) -> Scene:
    """Bytes of an `lcmt_viewer_load_robot` straight to a scene."""
    return scene_from_load(LOAD_ROBOT.decode(data))


# --- scene -> load_robot -------------------------------------------------------------------------


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


def geometry_to_lcm(geometry: Geometry) -> LcmMessage:
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


def link_to_lcm(link: Link) -> LcmMessage:
    geoms = per_geometry(link, lambda _, geometry: geometry_to_lcm(geometry))
    return LINK_DATA.message_class(name=link.name, robot_num=link.robot_num, num_geom=len(geoms), geom=geoms)


def load_from_scene(scene: Scene) -> LcmMessage:
    """The `lcmt_viewer_load_robot` that describes the scene's geometry."""
    links = [link_to_lcm(link) for link in scene.links]
    return LOAD_ROBOT.message_class(num_links=len(links), link=links)


# --- draw <-> poses ------------------------------------------------------------------------------


def poses_from_draw(message: LcmMessage) -> LinkPoses:
    """A decoded `lcmt_viewer_draw` as arrays (copies, native float64)."""
    count = message.num_links
    return LinkPoses(
        timestamp_ms=message.timestamp,
        names=tuple(message.link_name),
        robot_nums=np.asarray(message.robot_num, dtype=np.int32).reshape(count),
        positions=np.asarray(message.position, dtype=np.float64).reshape(count, 3),
        quaternions_wxyz=np.asarray(message.quaternion, dtype=np.float64).reshape(count, 4),
    )


def draw_from_poses(poses: LinkPoses) -> LcmMessage:
    """The `lcmt_viewer_draw` message of a frame (float32 on the wire, as Drake sends it)."""
    return DRAW.message_class(
        timestamp=int(poses.timestamp_ms),
        num_links=len(poses),
        link_name=list(poses.names),
        robot_num=[int(value) for value in poses.robot_nums],
        position=np.asarray(poses.positions, dtype=np.float64).tolist(),
        quaternion=np.asarray(poses.quaternions_wxyz, dtype=np.float64).tolist(),
    )


_HEADER = struct.Struct(">qi")
_BIG_F32, _BIG_I32 = np.dtype(">f4"), np.dtype(">i4")
_TIMESTAMP = struct.Struct(">q")
_U32 = struct.Struct(">I")
_NAMES_AT = 20  # fingerprint (8), timestamp (8), num_links (4)


@dataclass(frozen=True, slots=True)
class _DrawLayout:
    """What a draw's names and robot numbers imply: the names, and where the floats sit.

    `key` is the draw's bytes from `num_links` to the end of the robot numbers; a draw that
    has the same bytes there (compared in place) and is `size` bytes long has these names and
    robot numbers (the robot numbers are a view of the key), and its floats at `floats_at`.
    """

    key: bytes
    names: tuple[str, ...]
    robot_nums: npt.NDArray[np.int32]
    size: int
    floats_at: int  # position (N x 3), then quaternion (N x 4), float32, to the end

    @classmethod
    def after_names(cls, data: bytes, names_end: int, names: tuple[str, ...]) -> _DrawLayout | None:
        """The layout, or None when `data` is not as long as these names make a draw."""
        count = len(names)
        floats_at = names_end + 4 * count  # after an int32 robot_num per link
        if len(data) != floats_at + 28 * count:
            return None
        key = bytes(data[_NAMES_AT - 4 : floats_at])
        robot_nums = np.frombuffer(key, _BIG_I32, count, len(key) - 4 * count)
        return cls(key, names, robot_nums, len(data), floats_at)


_FINGERPRINT = DRAW.packed_fingerprint
_NO_LAYOUT = _DrawLayout(b"", (), np.zeros(0, dtype=np.int32), -1, 0)


class DrawDecoder:
    """Fast `lcmt_viewer_draw` decoding into numpy arrays.

    The link names and robot numbers rarely change between frames, so what they imply is kept
    and reused while the next frame has the same bytes there: a memory comparison and a length
    check instead of N string decodes. The positions and quaternions come back as native
    float32 arrays (views of one copy of the draw's floats, checked finite), the robot numbers
    as a read-only big-endian int32 array. One decoded draw may feed several routes: never
    change the arrays. Anything irregular is handed to the generic decoder, so the same inputs
    raise the same `DecodeError`s as `DRAW.decode`.
    """

    def __init__(self) -> None:
        # One object holding names, robot numbers and offsets: replaced in one store, so routes
        # sharing a decoder on several threads never see one draw's names with another's offsets.
        self._layout = _NO_LAYOUT

    def decode(self, data: Buffer) -> LinkPoses:
        if not isinstance(data, bytes):
            data = bytes(data)  # bytes compare in place; a view of a copy stays valid
        known = self._layout
        layout = (
            known
            if len(data) == known.size
            and data.startswith(_FINGERPRINT)
            and data.startswith(known.key, _NAMES_AT - 4)
            else self._new_layout(data)
        )
        if layout is None:
            return self._generic(data)
        # One copy of the floats, native and from an aligned copy of the bytes (numpy swaps
        # unaligned data at a third of the speed): checked here, and what every consumer gets,
        # since aligned native arrays are what numpy computes with fastest.
        floats: np.ndarray[Any, Any] = np.frombuffer(data[layout.floats_at :], _BIG_F32).astype(np.float32)
        count = len(layout.names)
        if 0 in np.isfinite(floats).tobytes():  # a False; faster than numpy's own counting
            return self._generic(data)  # which names the field and offset
        return LinkPoses.of_arrays(
            _TIMESTAMP.unpack_from(data, 8)[0],
            layout.names,
            layout.robot_nums,
            floats[: 3 * count].reshape(count, 3),
            floats[3 * count :].reshape(count, 4),
        )

    @staticmethod
    def _generic(data: Buffer) -> LinkPoses:
        return poses_from_draw(DRAW.decode(data))

    def _new_layout(self, data: bytes) -> _DrawLayout | None:
        """Parse the name block and keep its layout; None when the draw is not well formed."""
        if len(data) < _NAMES_AT or not data.startswith(_FINGERPRINT):
            return None
        _, count = _HEADER.unpack_from(data, 8)
        parsed = _parse_names(data, count)
        if parsed is None:
            return None
        layout = _DrawLayout.after_names(data, *parsed)
        if layout is not None:
            self._layout = layout
        return layout


def _parse_names(data: bytes, count: int) -> tuple[int, tuple[str, ...]] | None:
    """(where the name block ends, the names), or None when it is not well formed."""
    end = len(data)
    if count < 0 or 37 * count > end - _NAMES_AT:  # at least 5 bytes of name + 32 of arrays per link
        return None
    names = []
    offset = _NAMES_AT
    for _ in range(count):
        if offset + 4 > end:
            return None
        (length,) = _U32.unpack_from(data, offset)
        start = offset + 4
        offset = start + length
        if length == 0 or offset > end or data[offset - 1] != 0:
            return None
        try:
            names.append(str(data[start : offset - 1], "utf-8"))
        except UnicodeDecodeError:
            return None
    return offset, tuple(names)


class DrawEncoder:
    """Fast `lcmt_viewer_draw` encoding from arrays, byte-identical to `DRAW.encode`.

    Like the decoder it keeps the encoded name block while the names repeat.
    """

    def __init__(self) -> None:
        self._names: tuple[str, ...] = ()
        self._names_block = b""

    def encode(self, poses: LinkPoses) -> bytes:
        count = len(poses)
        if poses.names != self._names:
            self._names_block = b"".join(_encode_string(name) for name in poses.names)
            self._names = tuple(poses.names)
        positions = np.asarray(poses.positions)
        quaternions = np.asarray(poses.quaternions_wxyz)
        if positions.shape != (count, 3) or quaternions.shape != (count, 4) or len(poses.robot_nums) != count:
            raise EncodeError(DRAW.type_name, "position", f"arrays do not match {count} links")
        return b"".join(
            (
                DRAW.packed_fingerprint,
                _HEADER.pack(poses.timestamp_ms, count),
                self._names_block,
                np.asarray(poses.robot_nums, dtype=">i4").tobytes(),
                _to_float32(positions, "position"),
                _to_float32(quaternions, "quaternion"),
            )
        )


def _to_float32(values: np.ndarray[Any, Any], field: str) -> bytes:
    narrowed = values.astype(">f4")
    # struct.pack('>f'), and so lcm-gen, refuses a value that only rounds to inf; numpy does not.
    if np.isinf(narrowed).any() and (np.isinf(narrowed) & ~np.isinf(values)).any():
        raise EncodeError(DRAW.type_name, field, "value out of range for float32")
    return narrowed.tobytes()


def _encode_string(text: str) -> bytes:
    data = text.encode("utf-8")
    return _U32.pack(len(data) + 1) + data + b"\0"


__all__ = [
    "TABLES",
    "DrawDecoder",
    "DrawEncoder",
    "decode_load",
    "draw_from_poses",
    "geometry_from_lcm",
    "geometry_to_lcm",
    "link_from_lcm",
    "link_to_lcm",
    "load_from_scene",
    "poses_from_draw",
    "scene_from_load",
]
