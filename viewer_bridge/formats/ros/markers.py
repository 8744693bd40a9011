"""A scene's markers as a ROS 2 `visualization_msgs/MarkerArray`, written as CDR directly.

`marker_specs` makes one `MarkerSpec` per marker from the `marker` table of `mappings/ros.yaml`;
`marker_array_cdr` writes them in the world frame (`marker_array_in_link_frames_cdr`: in their
links' frames). `MarkerStream`: one load -> a CDR template of the array, then each draw only
writes the markers' world poses into it.
"""

from __future__ import annotations

import struct
import threading
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

from viewer_bridge.formats.ros.cdr import (
    CDR_LE,
    CDR_TIME,
    FRONT_PADDING,
    POSE_ITEM,
    U32,
    CdrWriter,
    cdr_string_4,
    payload_items,
)
from viewer_bridge.formats.ros.tables import TABLES
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
_IDENTITY_XYZW = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
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


_ID_TYPE_ACTION = struct.Struct("<iii")
# pose (7), scale (3), color (4 float32), lifetime (sec, nanosec): one block, 8-aligned.
_POSE_TO_LIFETIME = struct.Struct("<10d4fiI")


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
        specs = [DELETE_ALL, *specs]
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
            prefix = CDR_TIME.pack(0, 0) + cdr_string_4(frame, "header.frame_id") + cdr_string_4(spec.ns)
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
    """The scene as MarkerArray CDR in the world frame, written without message objects.

    Each marker's pose is its link's pose in `scene.poses` times the geometry's pose (a link
    missing from the poses, like `world`, sits at the origin). `options` override the table's
    (`frame_id`, `embed_mesh_files`). With `delete_all` the array starts with a DELETEALL marker,
    as a new load should, so that RViz forgets the previous scene.
    """
    frame_id = str(marker_settings(options)["frame_id"])
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

    def __init__(self, scene: Scene, options: dict[str, object] | None = None) -> None:
        frame_id = str(marker_settings(options)["frame_id"])
        self._specs = marker_specs(scene, options)
        positions, wxyz = world_poses(scene, self._specs)
        poses = pose_rows_xyzw(positions, wxyz)
        self.load_cdr = _write_markers(self._specs, poses, frame_id, delete_all=True)[0]
        self._template, offsets = _write_markers(self._specs, poses, frame_id, delete_all=False)
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
