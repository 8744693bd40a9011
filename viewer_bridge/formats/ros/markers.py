"""A scene's markers as a ROS 2 `visualization_msgs/MarkerArray`, written as CDR by the generated
writer (`lcmcodec.ros_writer`), without message objects.

`marker_specs` makes one `MarkerSpec` per marker from the `marker` table of `mappings/ros.yaml`;
`marker_array_cdr` writes them in the world frame (`marker_array_in_link_frames_cdr`: in their
links' frames). The markers are written at the origin and their poses put in afterwards, all
at once, where the writer marked them. `MarkerStream`: one load -> a CDR template of the array,
then each draw only writes the markers' world poses into it.
"""

from __future__ import annotations

import struct
import threading
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

from viewer_bridge.formats.ros.cdr import FRONT_PADDING, POSE_ITEM, payload_items
from viewer_bridge.formats.ros.tables import TABLES
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.pose_math import PartsOnLinks, pose_rows_xyzw, wxyz_from_xyzw
from viewer_bridge.model.scene import FloatArray, Geometry, LinkPoses, Pose, Scene
from viewer_bridge.model.skipped import per_geometry


class MarkerSpec(NamedTuple):
    """One marker of a load, before it is bytes: what the CDR path (and the tests' objects) write.

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
DELETE_ALL = MarkerSpec("", "", 0, 0, Pose(), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), action=3)


_FLOAT32X4 = struct.Struct("<4f")


def marker_specs(scene: Scene, options: dict[str, Any] | None = None) -> list[MarkerSpec]:
    """The markers of a scene, by `mappings/ros.yaml` (`options` override the table's options).

    The namespace is the link's frame name and ids count the link's marker parts, so a marker
    keeps its ns/id from one load of the same scene to the next. A geometry that cannot be
    written (a mesh file to embed that cannot be read) is skipped alone.
    """
    table = TABLES["marker"]
    settings = marker_settings(options)
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


def marker_settings(options: dict[str, Any] | None) -> dict[str, Any]:
    """The marker table's options (`frame_id`, `embed_mesh_files`, ...), `options` overriding them."""
    return {**TABLES["marker"].options, **(options or {})}


_POSE = "markers.pose"  # marked: every marker's pose is written after the rest, all at once
_ORIGIN = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
_STAMP = (0, 0)  # header.stamp and lifetime: none (a lifetime of 0 is forever)
_NO_TEXTURE = ((_STAMP, ""), "", b"")  # sensor_msgs/CompressedImage


def _marker_array(
    specs: Sequence[MarkerSpec], frame_id: str | Sequence[str], delete_all: bool, frame_locked: bool = False
) -> tuple[bytes, list[int]]:
    """A MarkerArray's CDR with every marker at the origin, and the payload offset of each spec's
    pose (`_posed` writes them in).

    `frame_id` is every marker's frame, or one frame per spec (markers in their links' frames,
    then `frame_locked`). With `delete_all` a DELETEALL marker comes first.
    """
    one_frame = isinstance(frame_id, str)
    headers = [(_STAMP, frame_id)] * len(specs) if one_frame else [(_STAMP, frame) for frame in frame_id]
    if delete_all:
        specs = [DELETE_ALL, *specs]
        headers = [headers[0] if headers else (_STAMP, ""), *headers]
    # Jazzy's Marker field by field: header, ns, id, type, action, pose, scale, color, lifetime,
    # frame_locked, points, colors, texture_resource, texture, uv_coordinates, text,
    # mesh_resource, mesh_file, mesh_use_embedded_materials.
    markers = [
        (header, ns, id_, type_, action, _ORIGIN, scale, color, _STAMP, frame_locked,
         () if points is None else points, () if colors is None else colors, "", _NO_TEXTURE, (), "",
         mesh_resource, mesh_file, False)
        for (_, ns, id_, type_, _, scale, color, points, colors, mesh_resource, mesh_file, action), header
        in zip(specs, headers, strict=True)
    ]  # fmt: skip
    data, marks = ros_writer("visualization_msgs/msg/MarkerArray", (_POSE,)).write_marked((markers,))
    return data, marks[_POSE][1:] if delete_all else marks[_POSE]


def _posed(data: bytes, offsets: list[int], poses: FloatArray) -> bytes:
    """`data` with pose k (M x 7 rows: position, quaternion x y z w) at payload offset `offsets[k]`."""
    if not offsets:
        return data
    buffer = bytearray(data)
    rows = np.ascontiguousarray(poses, dtype="<f8").view(POSE_ITEM).reshape(-1)
    payload_items(buffer, POSE_ITEM, 8)[np.asarray(offsets) // 8] = rows
    return bytes(buffer)


def marker_array_cdr(scene: Scene, options: dict[str, Any] | None = None, delete_all: bool = True) -> bytes:
    """The scene as MarkerArray CDR in the world frame, written without message objects.

    Each marker's pose is its link's pose in `scene.poses` times the geometry's pose (a link
    missing from the poses, like `world`, sits at the origin). `options` override the table's
    (`frame_id`, `embed_mesh_files`). With `delete_all` the array starts with a DELETEALL marker,
    as a new load should, so that RViz forgets the previous scene.
    """
    frame_id = str(marker_settings(options)["frame_id"])
    specs = marker_specs(scene, options)
    positions, wxyz = world_poses(scene, specs)
    return _posed(*_marker_array(specs, frame_id, delete_all), pose_rows_xyzw(positions, wxyz))


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
    return _posed(*_marker_array(specs, frames, True, frame_locked=True), pose_rows_xyzw(positions, wxyz))


class MarkerStream:
    """A scene's `MarkerArray`, re-posed every draw without rebuilding it.

    Made from a load: the markers are written once as a CDR template, remembering where each
    pose's 7 float64 sit. `update(poses)` composes every marker's world pose with numpy and
    writes them into a copy of the template. `load_cdr` is the load's own MarkerArray
    (DELETEALL first), to be published once and latched.
    """

    def __init__(self, scene: Scene, options: dict[str, object] | None = None) -> None:
        frame_id = str(marker_settings(options)["frame_id"])
        self._specs = marker_specs(scene, options)
        positions, wxyz = world_poses(scene, self._specs)
        self.load_cdr = _posed(*_marker_array(self._specs, frame_id, True), pose_rows_xyzw(positions, wxyz))
        self._template, offsets = _marker_array(self._specs, frame_id, False)  # each update poses it
        # Poses are 8-aligned in the payload, which starts after the 4-byte encapsulation: in a
        # buffer with 4 bytes in front of the message, they are aligned for numpy. The buffer is
        # kept: every update rewrites all the poses and nothing else, then copies the message
        # out. Each marker's pose is one 56-byte item (`payload_items`), so one copy.
        self._buffer = np.empty(FRONT_PADDING + len(self._template), dtype=np.uint8)
        self._buffer[FRONT_PADDING:] = np.frombuffer(self._template, dtype=np.uint8)
        self._poses = payload_items(self._buffer, POSE_ITEM, 8, front=FRONT_PADDING)
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
            return self._buffer[FRONT_PADDING:].tobytes()


__all__ = [
    "DELETE_ALL",
    "MarkerSpec",
    "MarkerStream",
    "marker_array_cdr",
    "marker_array_in_link_frames_cdr",
    "marker_settings",
    "marker_specs",
    "world_poses",
]
