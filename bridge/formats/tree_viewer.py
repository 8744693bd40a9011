"""Director's remote tree viewer protocol (`treeviewer_json` 1.0) to and from the scene.

Requests are JSON objects with `setgeometry`, `settransform` and `delete` command lists, carried
in a `robotlocomotion.viewer2_comms_t` on `DIRECTOR_TREE_VIEWER_REQUEST_<client_id>`.

How a scene is laid out in the tree: each link is the node
`[*prefix, str(robot_num), link.name]`, whose transform is the link's world pose; each geometry
is a child `[..., str(index)]` whose setgeometry `transform` is its pose in the link frame.
Quaternions are `[w, x, y, z]`, as in Drake. A new load deletes `prefix` first.

`TreeState` is the other direction: it applies requests to a tree, answers them as Director
does (MISSING_PATHS included), and reads the tree back as a scene.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import cache
from typing import Any

import numpy as np
import numpy.typing as npt
import orjson

from bridge.errors import RequestRejected, SceneError
from bridge.lcmcodec import VIEWER2_COMMS, Buffer
from bridge.mappings import FormatTables
from bridge.scene import (
    FloatArray,
    Geometry,
    Line,
    Link,
    LinkPoses,
    MeshFile,
    PointCloud,
    Pose,
    Scene,
    Shape,
    TriangleMesh,
    unit_quaternions,
)
from bridge.skipped import per_geometry

FORMAT = "treeviewer_json"
VERSION = (1, 0)
DEFAULT_PREFIX: tuple[str, ...] = ("drake",)

# Response status codes (docs/PROTOCOLS.md section 2).
OK = 0
MISSING_PATHS = 1
ERROR_UNKNOWN_FORMAT = -1
ERROR_UNKNOWN_FORMAT_VERSION = -2
ERROR_HANDLING_REQUEST = -3
ERROR_UNKNOWN_REQUEST_TYPE = -4

Path = tuple[str, ...]
Request = dict[str, Any]


def request_channel(client_id: str) -> str:
    return f"DIRECTOR_TREE_VIEWER_REQUEST_<{client_id}>"


def response_channel(client_id: str) -> str:
    return f"DIRECTOR_TREE_VIEWER_RESPONSE_<{client_id}>"


# --- scene -> requests ----------------------------------------------------------------------------


def _mesh_data(shape: TriangleMesh) -> dict[str, Any]:
    return {"vertices": shape.vertices.tolist(), "faces": shape.triangles.tolist()}


def _pointcloud(shape: PointCloud) -> dict[str, Any]:
    channels = {name: list(values) for name, values in shape.channels.items()}
    if shape.colors is not None:
        channels["rgb"] = shape.colors.tolist()
    return {"points": shape.points.tolist(), "channels": channels}


def _line(shape: Line) -> dict[str, Any]:
    return {
        "points": shape.points.tolist(),
        "radius": shape.radius,
        "closed": shape.closed,
        "start_head": shape.start_head,
        "end_head": shape.end_head,
        "head_radius": shape.head_radius,
        "head_length": shape.head_length,
    }


TABLES = FormatTables("tree_viewer", {"mesh_data": _mesh_data, "pointcloud": _pointcloud, "line": _line})


def transform(pose: Pose) -> dict[str, list[float]]:
    return {"translation": list(pose.position), "quaternion": list(pose.quaternion_wxyz)}


def link_path(link: Link, prefix: Sequence[str] = DEFAULT_PREFIX) -> list[str]:
    return [*prefix, str(link.robot_num), link.name]


def geometry_command(shape: Shape, pose: Pose, color: Sequence[float]) -> dict[str, Any]:
    """The `geometry` object of a setgeometry for one shape (see mappings/tree_viewer.yaml)."""
    ((rule, lowered, lowered_pose),) = TABLES["geometry"].expand(shape, pose)
    return {"type": rule.type_code, **rule.values(lowered), "color": list(color), "transform": transform(lowered_pose)}


def load_requests(scene: Scene, prefix: Sequence[str] = DEFAULT_PREFIX, utime: int = 0) -> list[Request]:
    """A load as two requests: delete the old tree under `prefix`, then set every geometry.

    Two requests rather than one, because a viewer may apply `delete` after `setgeometry`
    within a request. If the scene has poses, the second request also sets the links' transforms.
    A geometry the format cannot hold (an in-memory mesh trimesh cannot read) is skipped.
    """
    commands = []
    for link in scene.links:
        path = link_path(link, prefix)

        def setgeometry(index: int, geometry: Geometry, path: list[str] = path) -> dict[str, Any]:
            command = geometry_command(geometry.shape, geometry.pose, geometry.color)
            return {"path": [*path, str(index)], "geometry": command}

        commands += per_geometry(link, setgeometry)
    settransform = draw_request(scene.poses, prefix, utime)["settransform"] if scene.poses else []
    return [
        _request(utime, delete=[{"path": list(prefix)}]),
        _request(utime, setgeometry=commands, settransform=settransform),
    ]


def draw_request(poses: LinkPoses, prefix: Sequence[str] = DEFAULT_PREFIX, utime: int = 0) -> Request:
    """A draw as one request of `settransform`s, one per link (robot_num from the draw itself).

    Its numbers are rounded to `DECIMALS` decimals (see `settransform_values`).
    """
    values = settransform_values(poses).tolist()
    commands = [
        {
            "path": [*prefix, str(int(robot_num)), name],
            "transform": {"translation": row[:3], "quaternion": row[3:]},
        }
        for name, robot_num, row in zip(poses.names, poses.robot_nums.tolist(), values, strict=True)
    ]
    return _request(utime or poses.timestamp_ms * 1000, settransform=commands)


# A settransform writes its numbers with 8 decimals: 5e-9 m or 5e-9 of a unit quaternion at most,
# under what a viewer can show and close to a float32's resolution (Drake's draws are float32).
# Shortest round-trip text costs about 45 ns a number even in orjson; fixed decimals let a draw
# be written from digit tables with a few numpy operations (`SettransformEncoder`).
DECIMALS = 8
_SCALE = 10.0**DECIMALS
# Beyond this a double has no 8th decimal to round to, and value * 10**8 could overflow to inf.
_ROUNDED_BELOW = 1e7


def settransform_values(poses: LinkPoses) -> FloatArray:
    """The N x 7 numbers of a draw's settransforms, [x, y, z, w, qx, qy, qz] per link, rounded to
    `DECIMALS` decimals (the double nearest to k / 10**DECIMALS, which is what parsing that
    decimal text gives); numbers of 10**7 or more in magnitude are left as they are."""
    values = np.concatenate((poses.positions, poses.quaternions_wxyz), axis=1, dtype=np.float64)
    with np.errstate(over="ignore"):  # the huge, kept as they are
        rounded = np.rint(values * _SCALE) / _SCALE
    return np.where(np.abs(values) < _ROUNDED_BELOW, rounded, values)


class SettransformEncoder:
    """A draw -> the envelope of its settransform request: the JSON values of
    `encode(draw_request(...))`, written faster.

    The JSON around the numbers depends only on the links (names, robot_nums) and the prefix,
    so it is kept per set of links as a table with one fixed-width row per link: the link's
    head (space-padded; JSON allows spaces between tokens), then eight 16-byte slots, the
    fourth holding `],"quaternion":[` and the others a number each, then the row's end.
    A number's slot is its separator, its sign and integer part right-aligned in spaces, the
    point, and the 8 decimals: three lookups in tables of digit groups (`_NumberTables`).
    A draw fills the slots with a few whole-array numpy operations and the request is the
    table's bytes. A draw with a number of 9,999 or more in magnitude is written by orjson.
    """

    _SLOT = 16
    _QUATERNION_SLOT = b'],"quaternion":['
    _ROW_END = (b"]}},", b"]}}")  # (between rows, after the last)
    _ROW_END_WIDTH = 8

    def __init__(self, prefix: Sequence[str] = DEFAULT_PREFIX) -> None:
        self.prefix = tuple(prefix)
        self._links: tuple[tuple[str, ...], bytes] | None = None
        self._rows = np.zeros((0, 0), np.uint8)
        self._slots = np.zeros((0, 8, 2), np.uint64)

    def encode(self, poses: LinkPoses, utime: int = 0) -> bytes:
        utime = int(utime or poses.timestamp_ms * 1000)
        start = b'{"timestamp":%d,"setgeometry":[],"settransform":[' % utime
        end = b'],"delete":[]}'
        if not len(poses):
            return envelope(start + end, utime)
        self._layout(poses)
        if not _number_tables().fill(self._slots, poses.positions, poses.quaternions_wxyz):
            return encode(draw_request(poses, self.prefix, utime), utime)
        return envelope(b"".join((start, self._rows.tobytes(), end)), utime)

    def _layout(self, poses: LinkPoses) -> None:
        robot_nums = poses.robot_nums.tobytes()
        if self._links is not None and self._links[1] == robot_nums and self._links[0] == poses.names:
            return
        heads = [
            b'{"path":'
            + orjson.dumps([*self.prefix, str(int(robot_num)), name])
            + b',"transform":{"translation":['
            for name, robot_num in zip(poses.names, poses.robot_nums.tolist(), strict=True)
        ]
        head_width = -(-max(map(len, heads)) // 8) * 8  # a multiple of 8, so the slots are uint64-aligned
        numbers = head_width + 8 * self._SLOT
        rows = np.full((len(heads), numbers + self._ROW_END_WIDTH), ord(" "), np.uint8)
        for row, head in zip(rows, heads, strict=True):
            row[head_width - len(head) : head_width] = np.frombuffer(head, np.uint8)
            row[numbers : numbers + 4] = np.frombuffer(self._ROW_END[0], np.uint8)
        rows[-1, numbers : numbers + 4] = np.frombuffer(self._ROW_END[1].ljust(4), np.uint8)
        rows[:, head_width + 3 * self._SLOT : head_width + 4 * self._SLOT] = np.frombuffer(
            self._QUATERNION_SLOT, np.uint8
        )
        self._rows = rows
        self._slots = rows.view(np.uint64)[:, head_width // 8 : numbers // 8].reshape(len(heads), 8, 2)
        self._links = (poses.names, robot_nums)


class _NumberTables:
    """The digit tables that write settransform numbers into 16-byte slots (`SettransformEncoder`).

    A slot is two uint64s. The first is 8 characters: the separator (a space before the first
    number of a list, else a comma), the sign and integer part right-aligned, and the point:
    one entry per (separator, sign, integer part < 10,000). The second is two entries of a
    table of the 4-digit groups 0000 to 9999 (uint32 each), the decimals.
    """

    _WHOLE_LIMIT = 10_000
    _GROUP = 10_000.0
    # Per number of [x, y, z, w, qx, qy, qz]: 1 where a comma comes before it.
    _AFTER_COMMA = np.array([0, 1, 1, 0, 1, 1, 1], np.float64)

    def __init__(self) -> None:
        wholes = [
            lead + b"%s%d." % (sign, whole)
            for lead in (b" ", b",")
            for sign in (b"", b"-")
            for whole in range(self._WHOLE_LIMIT)
        ]
        self.wholes = np.frombuffer(b"".join(text[:1] + text[1:].rjust(7) for text in wholes), np.uint64)
        self.groups = np.frombuffer(b"".join(b"%04d" % group for group in range(10_000)), np.uint32)
        self.offsets = self._AFTER_COMMA * (2 * self._WHOLE_LIMIT)

    def fill(self, slots: npt.NDArray[np.uint64], positions: FloatArray, quaternions: FloatArray) -> bool:
        """Writes a draw's numbers into `slots` (N x 8 x 2, slot 3 left alone); False, writing
        nothing, when a number is too large for a slot."""
        values = np.concatenate((positions, quaternions), axis=1, dtype=np.float64)
        magnitude = np.abs(values)
        if not magnitude.max() < self._WHOLE_LIMIT - 1:  # also False for NaN; the rest fit, rounded
            return False
        magnitude = np.rint(magnitude * _SCALE)  # |k|: rint rounds half to even, symmetric in sign
        whole = np.floor(magnitude / _SCALE)  # exact: k / 1e8 is never rounded up to the next integer
        fraction = magnitude - whole * _SCALE
        high = np.floor(fraction / self._GROUP)
        low = fraction - high * self._GROUP
        whole += self.offsets
        whole += np.signbit(values) * float(self._WHOLE_LIMIT)  # -0.0 too: a negative rounded to 0
        texts = np.empty((len(values), 7, 2), np.uint64)
        texts[:, :, 0] = self.wholes.take(whole.astype(np.intp))
        decimals = texts.view(np.uint32).reshape(len(values), 7, 4)
        decimals[:, :, 2] = self.groups.take(high.astype(np.intp))
        decimals[:, :, 3] = self.groups.take(low.astype(np.intp))
        slots[:, 0:3] = texts[:, 0:3]
        slots[:, 4:8] = texts[:, 3:7]
        return True


@cache
def _number_tables() -> _NumberTables:
    return _NumberTables()


def _request(utime: int, **commands: list[dict[str, Any]]) -> Request:
    return {
        "timestamp": int(utime),
        "setgeometry": commands.get("setgeometry", []),
        "settransform": commands.get("settransform", []),
        "delete": commands.get("delete", []),
    }


def encode(payload: Request, utime: int = 0) -> bytes:
    """A request or response in its `viewer2_comms_t` envelope."""
    data = orjson.dumps(payload)  # compact; several times faster than json for float-heavy loads
    return envelope(data, int(utime or _echo_time(payload)))


def envelope(data: bytes, utime: int) -> bytes:
    """JSON text already written, in its `viewer2_comms_t` envelope."""
    major, minor = VERSION
    return VIEWER2_COMMS.encode(
        VIEWER2_COMMS.message_class(
            utime=utime,
            format=FORMAT,
            format_version_major=major,
            format_version_minor=minor,
            num_bytes=len(data),
            data=data,
        )
    )


_ENVELOPE = VIEWER2_COMMS.type_name


def decode(data: Buffer) -> Request:
    """A `viewer2_comms_t` envelope's JSON object.

    Raises `DecodeError` for bytes that are no envelope, and `RequestRejected` (with the response
    status) for a wrong format or version, bad JSON, or JSON that is no object.
    """
    message = VIEWER2_COMMS.decode(data)
    if message.format != FORMAT:
        raise RequestRejected(ERROR_UNKNOWN_FORMAT, f"{_ENVELOPE}.format: unknown format {message.format!r}")
    major, minor = message.format_version_major, message.format_version_minor
    if major != VERSION[0]:
        raise RequestRejected(
            ERROR_UNKNOWN_FORMAT_VERSION, f"{_ENVELOPE}.format_version_major: unknown version {major}.{minor}"
        )
    try:
        payload = orjson.loads(bytes(message.data))
    except orjson.JSONDecodeError as error:  # also raised for invalid UTF-8
        position = getattr(error, "pos", getattr(error, "start", 0))
        raise RequestRejected(
            ERROR_HANDLING_REQUEST, f"{_ENVELOPE}.data at character {position}: not JSON: {error}"
        ) from None
    if not isinstance(payload, dict):
        raise RequestRejected(ERROR_HANDLING_REQUEST, f"{_ENVELOPE}.data: the JSON is not an object")
    return payload


# --- requests -> scene ----------------------------------------------------------------------------------


@dataclass
class _Node:
    children: dict[str, _Node] = field(default_factory=dict)
    transform: Pose = Pose()
    geometries: list[Geometry] = field(default_factory=list)

    def has_geometry(self) -> bool:
        return bool(self.geometries) or any(child.has_geometry() for child in self.children.values())


_REQUEST_KEYS = {"timestamp", "utime", "setgeometry", "settransform", "delete"}


class TreeState:
    """A tree viewer's tree: apply requests to it, read it back as a scene.

    A request is checked as a whole before anything is applied; then `delete` goes first, then
    `setgeometry`, then `settransform`. A settransform for a path with no geometry at or below
    it is reported as MISSING_PATHS, as Director does. `mesh_file` paths must lie below one of
    `mesh_roots` (no roots: no mesh files), since a viewer should not be told to read any file.
    """

    def __init__(self, mesh_roots: Sequence[str | os.PathLike[str]] = ()) -> None:
        self.root = _Node()
        self.timestamp_us = 0
        self.mesh_roots = [os.path.realpath(root) for root in mesh_roots]

    def respond(self, request: Request) -> dict[str, Any]:
        """Apply one request and answer it: status 0 or 1, or -3 / -4 with an `error` text."""
        try:
            return self.apply(request)
        except RequestRejected as error:
            return {"timestamp": _echo_time(request), "status": error.status, "error": str(error)}
        except SceneError as error:
            return {"timestamp": _echo_time(request), "status": ERROR_HANDLING_REQUEST, "error": str(error)}

    def apply(self, request: Request) -> dict[str, Any]:
        """Apply one request; returns the response payload (status, missing_paths).

        Raises `RequestRejected` (-4) for an unknown command and `SceneError` (-3) for a bad one;
        the tree is then unchanged.
        """
        unknown = sorted(set(request) - _REQUEST_KEYS)
        if unknown:
            raise RequestRejected(ERROR_UNKNOWN_REQUEST_TYPE, f"unknown command {unknown[0]!r}")
        timestamp = _timestamp(request)
        if timestamp != _echo_time(request):
            raise SceneError(f"timestamp must be an integer of microseconds, got {timestamp!r}")
        deletes = [
            _path(command, f"delete[{index}]") for index, command in enumerate(_commands(request, "delete"))
        ]
        geometries = [
            self._geometry_command(command, f"setgeometry[{index}]")
            for index, command in enumerate(_commands(request, "setgeometry"))
        ]
        transforms = []
        for index, command in enumerate(_commands(request, "settransform")):
            where = f"settransform[{index}]"
            transform = command.get("transform", {}) if isinstance(command, dict) else None
            transforms.append((_path(command, where), pose_from_transform(transform, f"{where}.transform")))
        for path in deletes:
            self._delete(path)
        for path, parsed in geometries:
            self._node(path, create=True).geometries = parsed
        missing = []
        for path, pose in transforms:
            node = self._node(path, create=True)
            node.transform = pose
            if not node.has_geometry():
                missing.append(list(path))
        self.timestamp_us = timestamp
        response: dict[str, Any] = {"timestamp": timestamp, "status": MISSING_PATHS if missing else OK}
        if missing:
            response["missing_paths"] = missing
        return response

    def _geometry_command(self, command: Any, where: str) -> tuple[Path, list[Geometry]]:
        path = _path(command, where)
        items = command.get("geometries", [command["geometry"]] if "geometry" in command else None)
        if not isinstance(items, list):
            raise SceneError(f"{where}: needs 'geometry' or 'geometries' (a list)")
        parsed = [geometry_from_command(item, f"{where}.geometry") for item in items]
        for geometry in parsed:
            if isinstance(geometry.shape, MeshFile):
                self._check_mesh_path(geometry.shape.path, where)
        return path, parsed

    def _check_mesh_path(self, path: str, where: str) -> None:
        try:
            real = os.path.realpath(path)
        except ValueError as error:  # e.g. an embedded NUL
            raise SceneError(f"{where}: mesh_file {path!r} is not a valid path ({error})") from None
        if not any(os.path.commonpath([real, root]) == root for root in self.mesh_roots):
            allowed = ", ".join(self.mesh_roots) or "none configured"
            raise SceneError(f"{where}: mesh_file {path} is outside the allowed folders ({allowed})")

    def _node(self, path: Path, create: bool) -> _Node:
        node = self.root
        for name in path:
            if name not in node.children:
                if not create:
                    raise KeyError(name)
                node.children[name] = _Node()
            node = node.children[name]
        return node

    def _delete(self, path: Path) -> None:
        if not path:
            self.root = _Node()
            return
        try:
            parent = self._node(path[:-1], create=False)
        except KeyError:
            return
        parent.children.pop(path[-1], None)

    def scene(self) -> Scene:
        """The tree as a scene: each node holding geometry becomes (part of) a link.

        A geometry at path P belongs to the link P[:-1] (its parent node), whose pose is the
        composition of the transforms from the root; the transform at P itself is folded into
        the geometry's pose. Links laid out as `load_requests` does ([..., robot_num, name])
        get their name and robot_num back; any other path is joined with `::`.
        """
        links: dict[Path, list[Geometry]] = {}
        link_poses: dict[Path, Pose] = {}
        self._collect(self.root, (), Pose(), Pose(), links, link_poses)
        scene_links, names, robot_nums, positions, quaternions = [], [], [], [], []
        for path, geometries in links.items():
            name, robot_num = _link_identity(path)
            scene_links.append(Link(name, robot_num, tuple(geometries)))
            names.append(name)
            robot_nums.append(robot_num)
            positions.append(link_poses[path].position)
            quaternions.append(link_poses[path].quaternion_wxyz)
        poses = LinkPoses(
            self.timestamp_us // 1000,
            tuple(names),
            np.asarray(robot_nums, dtype=np.int32),
            np.asarray(positions, dtype=np.float64).reshape(-1, 3),
            np.asarray(quaternions, dtype=np.float64).reshape(-1, 4),
        )
        return Scene(tuple(scene_links), poses)

    def _collect(
        self,
        node: _Node,
        path: Path,
        parent_pose: Pose,
        pose: Pose,
        links: dict[Path, list[Geometry]],
        link_poses: dict[Path, Pose],
    ) -> None:
        if node.geometries:
            link = path[:-1]
            links.setdefault(link, [])
            link_poses[link] = parent_pose
            for geometry in node.geometries:
                local = node.transform.compose(geometry.pose)
                links[link].append(Geometry(geometry.shape, local, geometry.color))
        for name, child in node.children.items():
            self._collect(child, (*path, name), pose, pose.compose(child.transform), links, link_poses)


def _timestamp(request: Request) -> Any:
    return request.get("timestamp", request.get("utime", 0))


def _echo_time(request: Request) -> int:
    """The request's time, to echo in a reply, when it is one (an int64); else 0."""
    value = _timestamp(request)
    valid = isinstance(value, int) and not isinstance(value, bool) and -(2**63) <= value < 2**63
    return value if valid else 0


def _link_identity(path: Path) -> tuple[str, int]:
    if len(path) >= 2 and path[-2].lstrip("-").isdigit():
        return path[-1], int(path[-2])
    return "::".join(path), 0


def _commands(request: Request, key: str) -> list[Any]:
    commands = request.get(key, [])
    if not isinstance(commands, list):
        raise SceneError(f"{key} is not a list")
    for index, command in enumerate(commands):
        if not isinstance(command, dict):
            raise SceneError(f"{key}[{index}] is not an object")
    return commands


def _path(command: Any, where: str) -> Path:
    path = command.get("path")
    if not isinstance(path, list) or not all(isinstance(part, str) for part in path):
        raise SceneError(f"{where}.path must be a list of strings")
    return tuple(path)


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


def scene_from_requests(
    requests: Iterable[Request], mesh_roots: Sequence[str | os.PathLike[str]] = ()
) -> Scene:
    """Apply requests to an empty tree and read the scene back."""
    state = TreeState(mesh_roots)
    for request in requests:
        state.apply(request)
    return state.scene()


__all__ = [
    "DECIMALS",
    "DEFAULT_PREFIX",
    "FORMAT",
    "MISSING_PATHS",
    "OK",
    "RequestRejected",
    "SettransformEncoder",
    "TreeState",
    "decode",
    "draw_request",
    "encode",
    "envelope",
    "geometry_command",
    "geometry_from_command",
    "load_requests",
    "request_channel",
    "response_channel",
    "scene_from_requests",
    "settransform_values",
]
