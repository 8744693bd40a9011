"""ROS 2 (Jazzy) messages to and from the scene model.

Messages are built as rosbags dataclasses (see `bridge.formats.ros_messages`, re-exported here:
`make`, `to_cdr`, `from_cdr`, `to_rclpy`, `from_rclpy`), so the converters work without a ROS
installation; `to_rclpy` turns any of them into rclpy message objects and `to_cdr` into the raw
CDR bytes an rclpy publisher accepts. The per-frame outputs also have fast paths that write CDR
straight from the pose arrays:

* `PoseArrayEncoder`: draw -> `geometry_msgs/PoseArray` bytes, `pose_array_arrays` back;
* `MarkerStream`: one load -> a CDR template of the `MarkerArray`, then each draw only writes
  the markers' world poses into it.

Which shape becomes which message is in `mappings/ros.yaml`; quaternion order is converted by
`bridge.scene` (`Pose.quaternion_xyzw`, `xyzw_from_wxyz`).
"""

from __future__ import annotations

import os
import struct
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from bridge.errors import DecodeError, SceneError
from bridge.formats.ros_messages import (
    CDR_LE,
    CDR_TIME,
    POSE_ITEM,
    U32,
    CdrWriter,
    cdr_string,
    from_cdr,
    from_rclpy,
    make,
    payload_items,
    stamp,
    time_parts,
    to_cdr,
    to_rclpy,
)
from bridge.mappings import FormatTables, ShapeRule
from bridge.scene import (
    FloatArray,
    Geometry,
    InMemoryMesh,
    Line,
    LinkPoses,
    MeshFile,
    PartsOnLinks,
    PointCloud,
    Pose,
    Scene,
    Shape,
    Triad,
    TriangleMesh,
    link_poses_from_xyzw,
    pose_from_xyzw,
    pose_rows_xyzw,
    write_pose_rows_xyzw,
    wxyz_from_xyzw,
)
from bridge.sim_time import ms_from_sec_nsec
from bridge.skipped import per_geometry

POSE_ARRAY = "geometry_msgs/msg/PoseArray"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
MARKER = "visualization_msgs/msg/Marker"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
SOLID_PRIMITIVE = "shape_msgs/msg/SolidPrimitive"
MESH = "shape_msgs/msg/Mesh"
PLANE = "shape_msgs/msg/Plane"

# --- poses ---------------------------------------------------------------------------------------


def header(frame_id: str, timestamp_ms: int = 0) -> Any:
    return make("std_msgs/msg/Header", stamp=stamp(timestamp_ms), frame_id=frame_id)


def pose_message(pose: Pose) -> Any:
    x, y, z = pose.position
    qx, qy, qz, qw = pose.quaternion_xyzw
    return make(
        "geometry_msgs/msg/Pose",
        position=make("geometry_msgs/msg/Point", x=x, y=y, z=z),
        orientation=make("geometry_msgs/msg/Quaternion", x=qx, y=qy, z=qz, w=qw),
    )


def pose_from_message(message: Any, what: str = "pose") -> Pose:
    """A `geometry_msgs/Pose` as a scene pose (checked: see `scene.pose_from_xyzw`)."""
    p, q = message.position, message.orientation
    return pose_from_xyzw([p.x, p.y, p.z], [q.x, q.y, q.z, q.w], what)


def pose_array(poses: LinkPoses, frame_id: str = "world") -> Any:
    """Every link's pose as one `geometry_msgs/PoseArray`, in the draw's link order."""
    return make(
        POSE_ARRAY,
        header=header(frame_id, poses.timestamp_ms),
        poses=[pose_message(poses.pose(index)) for index in range(len(poses))],
    )


def pose_stamped(poses: LinkPoses, index: int, frame_id: str = "world") -> Any:
    """One link's world pose as a `geometry_msgs/PoseStamped`."""
    return make(
        POSE_STAMPED, header=header(frame_id, poses.timestamp_ms), pose=pose_message(poses.pose(index))
    )


def poses_from_pose_array(
    message: Any, names: Sequence[str], robot_nums: Sequence[int] | None = None
) -> LinkPoses:
    """A `PoseArray` back as link poses; PoseArray carries no names, so the caller gives them.

    Raises `SceneError` when the counts differ or a pose is not finite or not a rotation.
    """
    positions = [[p.position.x, p.position.y, p.position.z] for p in message.poses]
    xyzw = [[p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] for p in message.poses]
    time = message.header.stamp
    timestamp_ms = ms_from_sec_nsec(time.sec, time.nanosec)
    return link_poses_from_xyzw(timestamp_ms, names, robot_nums, positions, xyzw, "poses")


def _stamp_bytes(timestamp_ms: int) -> bytes:
    return CDR_TIME.pack(*time_parts(timestamp_ms))


class PoseArrayEncoder:
    """draw arrays -> `geometry_msgs/PoseArray` CDR, without building a message per link.

    Layout (payload offsets after the 4-byte encapsulation header): stamp (int32 sec, uint32
    nanosec), frame_id string, pad to 4, uint32 count, pad to 8, then per pose 7 float64
    (position x y z, orientation x y z w). The bytes up to the count depend only on the frame id.
    The message is kept in one buffer per pose count: a draw writes its stamp and rows there and
    returns a copy. One encoder serves one thread at a time (a route's translations are serialised).
    """

    def __init__(self, frame_id: str = "world") -> None:
        self.frame_id = frame_id
        self._frame = _string_4(frame_id, "header.frame_id")
        self._padding = b"\0" * (-(8 + len(self._frame) + 4) % 8)
        self._layout(0)

    def encode(self, poses: LinkPoses) -> bytes:
        if len(poses) != len(self._rows):
            self._layout(len(poses))
        self._buffer[_ALIGNED + 4 : _ALIGNED + 12] = _stamp_bytes(poses.timestamp_ms)
        write_pose_rows_xyzw(self._rows, poses.positions, poses.quaternions_wxyz)
        return bytes(self._message)

    def _layout(self, count: int) -> None:
        head = b"".join((CDR_LE, bytes(8), self._frame, U32.pack(count), self._padding))
        self._buffer = bytearray(b"\0" * _ALIGNED + head + bytes(56 * count))
        self._message = memoryview(self._buffer)[_ALIGNED:]
        self._rows = np.frombuffer(self._buffer, dtype="<f8", offset=_ALIGNED + len(head)).reshape(count, 7)


class PoseStampedEncoder:
    """draw arrays -> one `geometry_msgs/PoseStamped` CDR per link, in the draw's order.

    Layout: stamp, frame_id string, pad to 8, 7 float64. Everything before the pose is the same
    for every link of a frame, so each message is that prefix plus 56 bytes of one row.
    """

    def __init__(self, frame_id: str = "world") -> None:
        self.frame_id = frame_id
        frame = cdr_string(frame_id, "header.frame_id")
        self._frame = frame + b"\0" * (-(8 + len(frame)) % 8)

    def encode(self, poses: LinkPoses) -> list[bytes]:
        prefix = CDR_LE + _stamp_bytes(poses.timestamp_ms) + self._frame
        return [prefix + row for row in map(bytes, pose_rows_xyzw(poses.positions, poses.quaternions_wxyz))]


def pose_array_arrays(data: bytes | memoryview) -> tuple[int, str, FloatArray, FloatArray]:
    """`PoseArray` CDR -> (timestamp_ms, frame_id, positions N x 3, quaternions N x 4 x-y-z-w).

    Raises `DecodeError` for bytes that are not a little-endian PoseArray.
    """
    buffer = memoryview(data)
    end = len(buffer)

    def fail(field: str, offset: int, reason: str) -> DecodeError:
        return DecodeError(POSE_ARRAY, field, offset, reason)

    if end < 16 or bytes(buffer[:4]) != CDR_LE:
        raise fail("", 0, "not little-endian CDR (encapsulation 00 01 00 00)")
    seconds, nanoseconds, length = struct.unpack_from("<iII", buffer, 4)
    frame_end = 16 + length
    if length == 0 or frame_end > end or buffer[frame_end - 1] != 0:
        raise fail("header.frame_id", 12, f"string of length {length} does not fit")
    frame_id = str(buffer[16 : frame_end - 1], "utf-8", errors="replace")
    count_at = _aligned(frame_end, 4)
    if count_at + 4 > end:
        raise fail("poses", count_at, "truncated before the count")
    (count,) = struct.unpack_from("<I", buffer, count_at)
    poses_at = _aligned(count_at + 4, 8)
    if end - poses_at != 56 * count:
        raise fail("poses", count_at, f"count {count} needs {56 * count} bytes, {end - poses_at} follow")
    values = np.frombuffer(buffer, dtype="<f8", count=7 * count, offset=poses_at).reshape(count, 7)
    timestamp_ms = ms_from_sec_nsec(seconds, nanoseconds)
    return timestamp_ms, frame_id, values[:, :3], values[:, 3:]


def _aligned(offset: int, boundary: int) -> int:
    """`offset` (in the buffer) moved up to CDR alignment, which counts from after the header."""
    return len(CDR_LE) + -(-(offset - len(CDR_LE)) // boundary) * boundary


def poses_from_pose_array_cdr(
    data: bytes | memoryview, names: Sequence[str], robot_nums: Sequence[int] | None = None
) -> LinkPoses:
    """The fast path of `poses_from_pose_array`: PoseArray CDR straight to link poses."""
    timestamp_ms, _, positions, xyzw = pose_array_arrays(data)
    return link_poses_from_xyzw(timestamp_ms, names, robot_nums, positions, xyzw, "poses")


# --- shapes: SolidPrimitive, Mesh, Plane -----------------------------------------------------------


@dataclass(frozen=True, slots=True)
class PosedShape:
    """One geometry as a shape_msgs message (`SolidPrimitive`, `Mesh` or `Plane`), posed in a frame."""

    frame_id: str
    pose: Any  # geometry_msgs/Pose
    shape: Any

    @property
    def typename(self) -> str:
        return str(self.shape.__msgtype__)


def shapes(scene: Scene) -> list[PosedShape]:
    """Every geometry of the scene as a shape_msgs message in its link's frame.

    A geometry that cannot be written (a mesh file that cannot be read) is skipped alone.
    """
    table = TABLES["shape"]
    result = []
    for link in scene.links:

        def posed(_: int, geometry: Geometry, frame: str = link.frame) -> list[PosedShape]:
            return [
                PosedShape(frame, pose_message(pose), _shape_message(rule, shape, table.target))
                for rule, shape, pose in table.expand(geometry.shape, geometry.pose)
            ]

        for parts in per_geometry(link, posed):
            result += parts
    return result


def shapes_cdr(scene: Scene) -> list[tuple[str, bytes]]:
    """`shapes` straight to CDR: (type name, bytes) per message, equal to `to_cdr` of each
    `PosedShape.shape`, written from the table's values and the mesh arrays (no message objects).

    Skips a geometry as `shapes` does.
    """
    table = TABLES["shape"]
    out = []
    # By id, holding the shape so that its id stays its own: lowered primitives share one
    # cached mesh, written once.
    written: dict[int, tuple[Shape, bytes]] = {}

    def messages(_: int, geometry: Geometry) -> list[tuple[str, bytes]]:
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
            parts.append((typename, data))
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
        (CDR_LE, _TYPE_AND_COUNT.pack(rule.type_code, count), struct.pack(f"<{count}d", *dimensions), U32.pack(0))
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


def _shape_message(rule: ShapeRule, shape: Shape, target: str) -> Any:
    values = rule.values(shape, {})
    typename = rule.message or target
    if rule.type_code is not None:
        values["type"] = rule.type_code
    return make(typename, **values)


def _mesh_message(shape: TriangleMesh, options: dict[str, Any]) -> dict[str, Any]:
    vertices = [make("geometry_msgs/msg/Point", x=x, y=y, z=z) for x, y, z in shape.vertices.tolist()]
    triangles = [
        make("shape_msgs/msg/MeshTriangle", vertex_indices=np.asarray(row, dtype=np.uint32))
        for row in shape.triangles
    ]
    return {"vertices": vertices, "triangles": triangles}


def shape_from_message(message: Any) -> Shape:
    """A `SolidPrimitive`, `Mesh` or `Plane` back as a scene shape (the reverse of `shapes`)."""
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


# --- markers -------------------------------------------------------------------------------------------


class MarkerSpec(NamedTuple):
    """One marker of a load, before it is a message: what both the object and CDR paths write.

    A named tuple: a load makes one per marker, and a frozen dataclass took as long to build
    as the rest of the load's markers together.

    `pose` is in the frame of link `link_name`; the marker's pose is that link's world pose
    times `pose`. `points` (K x 3) is for TRIANGLE_LIST; `mesh_file` = (filename, bytes) for an
    embedded mesh.
    """

    link_name: str
    ns: str
    id: int
    type: int
    pose: Pose
    scale: tuple[float, float, float]
    color: tuple[float, float, float, float]
    points: FloatArray | None = None
    colors: FloatArray | None = None  # K x 4 RGBA per point (POINTS, LINE_LIST)
    mesh_resource: str = ""
    mesh_file: tuple[str, bytes] = ("", b"")
    action: int = 0  # ADD; DELETEALL = 3


# The marker that starts a new load's array: RViz drops every marker it has.
_IDENTITY_XYZW = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
_DELETE_ALL = MarkerSpec("", "", 0, 0, Pose(), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), action=3)


_FLOAT32X4 = struct.Struct("<4f")


def marker_specs(scene: Scene, options: dict[str, Any] | None = None) -> list[MarkerSpec]:
    """The markers of a scene, by `mappings/ros.yaml` (`options` override the table's options).

    The namespace is the link's frame name and ids count the link's marker parts, so a marker
    keeps its ns/id from one load of the same scene to the next. A geometry that cannot be
    written (a mesh file to embed that cannot be read) is skipped alone.
    """
    table = TABLES["marker"]
    settings = _marker_settings(options)
    specs = []
    colors: dict[bytes, tuple[float, ...]] = {}  # a load has few distinct colours

    def parts(_: int, geometry: Geometry) -> list[tuple[Any, Pose, Any, Any, dict[str, Any]]]:
        # ColorRGBA is float32 on the wire: round here so objects equal their CDR. Cached by
        # the float32 bits, which tell -0.0 from 0.0 (equal floats, written differently).
        packed = _FLOAT32X4.pack(*geometry.color)
        color = colors.get(packed)
        if color is None:
            color = colors[packed] = _FLOAT32X4.unpack(packed)
        made = []
        for rule, shape, pose in table.expand(geometry.shape, geometry.pose):
            values = rule.values(shape, settings)
            scale = tuple(values.pop("scale"))
            # An encoder may choose another type for some shapes (a line with a head: ARROW).
            code = values.pop("type", rule.type_code if rule.type_code is not None else 0)
            made.append((code, pose, scale, color, values))
        return made

    for link in scene.links:
        name, ns = link.name, link.frame
        marker_id = 0
        for geometry_parts in per_geometry(link, parts):
            for code, pose, scale, color, values in geometry_parts:
                if values:  # an encoder's points, colours or mesh
                    specs.append(MarkerSpec(name, ns, marker_id, code, pose, scale, color, **values))
                else:
                    specs.append(MarkerSpec(name, ns, marker_id, code, pose, scale, color))
                marker_id += 1
    return specs


def world_poses(scene: Scene, specs: Sequence[MarkerSpec]) -> tuple[FloatArray, FloatArray]:
    """Every marker's world pose (positions M x 3, quaternions M x 4 w-first), all at once."""
    positions, wxyz = _part_poses(specs)
    if scene.poses is None:
        return positions, wxyz
    rows = _link_rows(scene.poses.names, [spec.link_name for spec in specs])
    world = PartsOnLinks(positions, wxyz).world_rows(
        scene.poses.positions, scene.poses.quaternions_wxyz, rows
    )
    return world[:, :3], wxyz_from_xyzw(world[:, 3:])


def _part_poses(specs: Sequence[MarkerSpec]) -> tuple[FloatArray, FloatArray]:
    """The markers' poses in their links' frames, as arrays."""
    positions = np.array([spec.pose.position for spec in specs], dtype=np.float64).reshape(-1, 3)
    wxyz = np.array([spec.pose.quaternion_wxyz for spec in specs], dtype=np.float64).reshape(-1, 4)
    return positions, wxyz


def _link_rows(names: Sequence[str], wanted: Sequence[str]) -> np.ndarray[Any, Any]:
    """The row of each wanted link in a draw; links the draw lacks get the extra identity row."""
    index = {name: row for row, name in enumerate(names)}
    return np.array([index.get(name, len(names)) for name in wanted], dtype=np.int64)


def _marker_settings(options: dict[str, Any] | None) -> dict[str, Any]:
    return {**TABLES["marker"].options, **(options or {})}


def marker_array(scene: Scene, options: dict[str, Any] | None = None, delete_all: bool = True) -> Any:
    """The scene as a `visualization_msgs/MarkerArray` (rosbags message) in the world frame.

    Each marker's pose is its link's pose in `scene.poses` times the geometry's pose (a link
    missing from the poses, like `world`, sits at the origin). `options` override the table's
    (`frame_id`, `embed_mesh_files`). With `delete_all` the array starts with a DELETEALL marker,
    as a new load should, so that RViz forgets the previous scene. `marker_array_cdr` is the
    fast path to the same message's bytes.
    """
    frame_id = str(_marker_settings(options)["frame_id"])
    specs = marker_specs(scene, options)
    positions, wxyz = world_poses(scene, specs)
    markers = [_marker_message(_DELETE_ALL, frame_id, Pose())] if delete_all else []
    for spec, position, quaternion in zip(specs, positions.tolist(), wxyz.tolist(), strict=True):
        markers.append(_marker_message(spec, frame_id, Pose(tuple(position), tuple(quaternion))))
    return make(MARKER_ARRAY, markers=markers)


def _marker_message(spec: MarkerSpec, frame_id: str, pose: Pose) -> Any:
    x, y, z = spec.scale
    r, g, b, a = spec.color
    extra: dict[str, Any] = {"mesh_resource": spec.mesh_resource}
    if spec.points is not None:
        extra["points"] = [
            make("geometry_msgs/msg/Point", x=px, y=py, z=pz) for px, py, pz in spec.points.tolist()
        ]
    if spec.colors is not None:  # float32 on the wire, rounded here as the CDR path does
        rgba = np.asarray(spec.colors, dtype=np.float32).tolist()
        extra["colors"] = [make("std_msgs/msg/ColorRGBA", r=r, g=g, b=b, a=a) for r, g, b, a in rgba]
    if spec.mesh_file[0]:
        name, data = spec.mesh_file
        extra["mesh_file"] = make(
            "visualization_msgs/msg/MeshFile", filename=name, data=np.frombuffer(data, np.uint8)
        )
    return make(
        MARKER,
        header=header(frame_id),
        ns=spec.ns,
        id=spec.id,
        type=spec.type,
        action=spec.action,
        pose=pose_message(pose),
        scale=make("geometry_msgs/msg/Vector3", x=x, y=y, z=z),
        color=make("std_msgs/msg/ColorRGBA", r=r, g=g, b=b, a=a),
        **extra,
    )


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
        "mesh": _mesh_message,
        "mesh_resource": _mesh_resource,
        "embedded_mesh": _embedded_mesh,
        "triangle_list": _triangle_list,
        "points": _points,
        "triad": _triad,
        "line_strip": _line_strip,
    },
)


# --- the MarkerArray fast path ---------------------------------------------------------------------


_ID_TYPE_ACTION = struct.Struct("<iii")
# pose (7), scale (3), color (4 float32), lifetime (sec, nanosec): one block, 8-aligned.
_POSE_TO_LIFETIME = struct.Struct("<10d4fiI")


def _string_4(text: str, field: str = "string") -> bytes:
    """A CDR string padded to a multiple of 4, for a string that starts 4-aligned."""
    data = cdr_string(text, field)
    return data + b"\0" * (-len(data) % 4)


def _marker_tail(spec: MarkerSpec, frame_locked: bool) -> bytes:
    """Everything after a marker's lifetime. It starts 8-aligned, so its bytes never change."""
    writer = CdrWriter()
    writer.add(b"\1" if frame_locked else b"\0")  # frame_locked: follow the frame as TF moves it
    points = spec.points if spec.points is not None else np.zeros((0, 3))
    writer.pack(U32, len(points))
    if len(points):
        writer.align(8)
        writer.add(np.ascontiguousarray(points, dtype="<f8").tobytes())
    colors = spec.colors if spec.colors is not None else np.zeros((0, 4))
    writer.pack(U32, len(colors))
    writer.add(np.ascontiguousarray(colors, dtype="<f4").tobytes())
    writer.string("")  # texture_resource
    writer.pack(CDR_TIME, 0, 0)  # texture.header.stamp
    writer.string("")  # texture.header.frame_id
    writer.string("")  # texture.format
    writer.octets(b"")  # texture.data
    writer.pack(U32, 0)  # uv_coordinates
    writer.string("")  # text
    writer.string(spec.mesh_resource)
    writer.string(spec.mesh_file[0])
    writer.octets(spec.mesh_file[1])
    writer.add(b"\0")  # mesh_use_embedded_materials
    return writer.getvalue()[len(CDR_LE) :]


def _write_markers(
    specs: Sequence[MarkerSpec],
    poses: FloatArray,
    frame_id: str | Sequence[str],
    delete_all: bool,
    frame_locked: bool = False,
) -> tuple[bytes, list[int]]:
    """A MarkerArray's CDR (Jazzy field order) and the payload offset of each spec's pose.

    `frame_id` is every marker's frame, or one frame per spec (markers in their links' frames,
    then `frame_locked`). Written a marker at a time from a few pre-packed blocks: the header
    (cached per frame), the namespace, one struct for pose to lifetime, and the tail (cached per
    kind of marker).
    """
    frames = [frame_id] * len(specs) if isinstance(frame_id, str) else list(frame_id)
    if delete_all:
        specs = [_DELETE_ALL, *specs]
        frames = [frames[0] if frames else "", *frames]
        poses = np.concatenate((_IDENTITY_XYZW[None, :], poses))
    prefixes: dict[tuple[str, str], bytes] = {}  # stamp, frame_id, ns: a link's markers share one
    tails: dict[tuple[str, str, int], bytes] = {}
    blocks = _blocks(specs, poses)
    block_size = _POSE_TO_LIFETIME.size
    chunks = [CDR_LE, U32.pack(len(specs))]
    size = 4  # payload bytes so far
    offsets = []
    for index, (spec, frame) in enumerate(zip(specs, frames, strict=True)):
        if size % 4:  # the previous marker ended on a bool
            chunks.append(_PADDING[-size % 4])
            size += -size % 4
        prefix = prefixes.get((frame, spec.ns))
        if prefix is None:
            prefix = CDR_TIME.pack(0, 0) + _string_4(frame, "header.frame_id") + _string_4(spec.ns)
            prefixes[(frame, spec.ns)] = prefix
        head = prefix + _ID_TYPE_ACTION.pack(spec.id, spec.type, spec.action)
        head_end = size + len(head)
        padding = -head_end % 8
        if spec.points is None and spec.colors is None:  # the tail depends on the mesh fields only
            key = (spec.mesh_resource, spec.mesh_file[0], id(spec.mesh_file[1]))
            tail = tails.get(key)
            if tail is None:
                tail = tails[key] = _marker_tail(spec, frame_locked)
        else:
            tail = _marker_tail(spec, frame_locked)
        offsets.append(head_end + padding)
        chunks += (head, _PADDING[padding], blocks[index * block_size : (index + 1) * block_size], tail)
        size = head_end + padding + block_size + len(tail)
    return b"".join(chunks), offsets[1:] if delete_all else offsets


_PADDING = [b"\0" * count for count in range(8)]

# `_POSE_TO_LIFETIME` as a numpy record, to write every marker's block at once.
_BLOCK = np.dtype([("pose", "<f8", 7), ("scale", "<f8", 3), ("color", "<f4", 4), ("lifetime", "<u4", 2)])
assert _BLOCK.itemsize == _POSE_TO_LIFETIME.size


def _blocks(specs: Sequence[MarkerSpec], poses: FloatArray) -> bytes:
    """Every marker's pose, scale, colour and lifetime (zero), packed as `_POSE_TO_LIFETIME`."""
    blocks = np.zeros(len(specs), dtype=_BLOCK)
    if not specs:
        return b""
    blocks["pose"] = poses
    blocks["scale"] = [spec.scale for spec in specs]
    blocks["color"] = [spec.color for spec in specs]  # float32 values already (see marker_specs)
    return blocks.tobytes()


def marker_array_cdr(scene: Scene, options: dict[str, Any] | None = None, delete_all: bool = True) -> bytes:
    """`marker_array` straight to CDR bytes, without building message objects (the fast path)."""
    frame_id = str(_marker_settings(options)["frame_id"])
    specs = marker_specs(scene, options)
    positions, wxyz = world_poses(scene, specs)
    return _write_markers(specs, pose_rows_xyzw(positions, wxyz), frame_id, delete_all)[0]


def marker_array_in_link_frames_cdr(
    scene: Scene, frame_of: Callable[[str], str], options: dict[str, Any] | None = None
) -> bytes:
    """The scene's markers, each in its link's frame (`frame_of(link name)`), `frame_locked`.

    Published once per load: the markers never change while TF moves their frames, so a draw
    costs one TFMessage instead of a re-posed MarkerArray. DELETEALL first, like a load's array.
    """
    specs = marker_specs(scene, options)
    positions, wxyz = _part_poses(specs)
    frames = [frame_of(spec.link_name) for spec in specs]
    return _write_markers(specs, pose_rows_xyzw(positions, wxyz), frames, True, frame_locked=True)[0]


class MarkerStream:
    """A scene's `MarkerArray`, re-posed every draw without rebuilding it.

    Made from a load: the markers are written once as a CDR template, remembering where each
    pose's 7 float64 sit. `update(poses)` composes every marker's world pose with numpy and
    writes them into a copy of the template. `load_cdr` is the load's own MarkerArray
    (DELETEALL first), to be published once and latched.
    """

    def __init__(self, scene: Scene, options: dict[str, Any] | None = None) -> None:
        frame_id = str(_marker_settings(options)["frame_id"])
        self._specs = marker_specs(scene, options)
        positions, wxyz = world_poses(scene, self._specs)
        poses = pose_rows_xyzw(positions, wxyz)
        self.load_cdr = _write_markers(self._specs, poses, frame_id, delete_all=True)[0]
        self._template, offsets = _write_markers(self._specs, poses, frame_id, delete_all=False)
        # Poses are 8-aligned in the payload, which starts after the 4-byte encapsulation: in a
        # buffer with 4 bytes in front of the message, they are aligned for numpy. The buffer is
        # kept: every update rewrites all the poses and nothing else, then copies the message
        # out. Each marker's pose is one 56-byte item (`payload_items`), so one copy.
        self._buffer = np.empty(_ALIGNED + len(self._template), dtype=np.uint8)
        self._buffer[_ALIGNED:] = np.frombuffer(self._template, dtype=np.uint8)
        self._poses = payload_items(self._buffer, POSE_ITEM, 8, front=_ALIGNED)
        self._pose_at = np.asarray(offsets, dtype=np.intp) // 8
        self._lock = threading.Lock()  # routes on several threads may share a stream
        self._link_names = [spec.link_name for spec in self._specs]
        self._parts = PartsOnLinks(*_part_poses(self._specs))
        self._rows_for: tuple[tuple[str, ...], np.ndarray[Any, Any]] = ((), np.zeros(0, dtype=np.int64))

    def __len__(self) -> int:
        return len(self._specs)

    def update(self, poses: LinkPoses) -> bytes:
        """The MarkerArray CDR with every marker at its link's pose in `poses`."""
        if poses.names is not self._rows_for[0] and poses.names != self._rows_for[0]:
            self._rows_for = (poses.names, _link_rows(poses.names, self._link_names))
        rows = self._parts.world_rows(poses.positions, poses.quaternions_wxyz, self._rows_for[1])
        with self._lock:
            self._poses[self._pose_at] = np.ascontiguousarray(rows).view(POSE_ITEM).reshape(-1)
            return self._buffer[_ALIGNED:].tobytes()


_ALIGNED = 4  # bytes in front of the message, so that its 8-aligned payload offsets are aligned


__all__ = [
    "MARKER_ARRAY",
    "MarkerSpec",
    "POSE_ARRAY",
    "POSE_STAMPED",
    "MarkerStream",
    "PoseArrayEncoder",
    "PoseStampedEncoder",
    "PosedShape",
    "from_cdr",
    "from_rclpy",
    "make",
    "marker_array",
    "marker_array_cdr",
    "marker_array_in_link_frames_cdr",
    "marker_specs",
    "pose_array",
    "pose_array_arrays",
    "pose_from_message",
    "pose_message",
    "pose_stamped",
    "poses_from_pose_array",
    "poses_from_pose_array_cdr",
    "shape_from_message",
    "shapes",
    "shapes_cdr",
    "to_cdr",
    "to_rclpy",
    "world_poses",
]
