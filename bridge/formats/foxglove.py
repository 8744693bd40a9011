"""Foxglove's 3D messages (foxglove-schemas-protobuf): the scene as `foxglove.SceneUpdate`, a draw as
`foxglove.FrameTransforms`.

The scene goes out once per load as one SceneEntity per link, in the link's frame and
frame_locked, with a primitive per geometry by `mappings/foxglove.yaml` (meshes embedded as
binary glTF from `bridge.formats.gltf`). A draw is then one FrameTransforms: world -> each link
frame, named as on ROS's /tf (`bridge.formats.ros.tf.FrameNames`).

`FrameTransformsEncoder` writes the FrameTransforms bytes straight from the draw arrays: the
protobuf wire layout per set of link names is a template (every field written, zeros too, which
any parser reads as the same message), and a draw scatters its doubles and its stamp into a copy.
`frame_transforms` builds the same message with the protobuf classes: the reference.
"""

from __future__ import annotations

import importlib
import struct
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from bridge.formats.gltf import write_gltf
from bridge.formats.protowire import key as _key
from bridge.formats.protowire import length_delimited as _length_delimited
from bridge.formats.protowire import varint as _varint
from bridge.formats.ros.tf import FrameNames
from bridge.lowering import triangle_mesh
from bridge.mappings import FormatTables
from bridge.scene import Geometry, Line, Link, LinkPoses, Pose, Scene, Shape, Triad, xyzw_from_wxyz
from bridge.skipped import per_geometry

SCENE_UPDATE = "foxglove.SceneUpdate"
FRAME_TRANSFORMS = "foxglove.FrameTransforms"


# --- load -> SceneUpdate ----------------------------------------------------------------------------


def scene_update(scene: Scene, frames: Callable[[str], str], stamp: tuple[int, int] = (0, 0)) -> Any:
    """The scene as a SceneUpdate: an entity per link with geometry to draw, in its link's frame."""
    table = TABLES["primitive"]
    update = SceneUpdate()

    def primitives(_: int, geometry: Geometry) -> Any:
        """The geometry's primitives in an entity of their own: merged once all are made."""
        part = SceneEntity()
        for rule, shape, pose in table.expand(geometry.shape, geometry.pose):
            primitive = getattr(part, rule.type_code).add()
            _set_pose(primitive.pose, pose)
            _set_fields(primitive, rule.values(shape))
            _set_color(primitive, geometry.color)
        return part

    for link in scene.links:
        parts = per_geometry(link, primitives)
        if not parts:
            continue
        entity = update.entities.add(id=link.name, frame_id=frames(link.name), frame_locked=True)
        entity.timestamp.seconds, entity.timestamp.nanos = stamp
        for part in parts:
            entity.MergeFrom(part)
    return update


def _set_pose(target: Any, pose: Pose) -> None:
    target.position.x, target.position.y, target.position.z = pose.position
    orientation = target.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = pose.quaternion_xyzw


def _set_fields(primitive: Any, values: dict[str, Any]) -> None:
    for name, value in values.items():
        if primitive.DESCRIPTOR.fields_by_name[name].is_repeated:  # points, colors: one dict each
            field = getattr(primitive, name)
            for item in value:
                field.add(**item)
        elif isinstance(value, list):  # a Vector3
            target = getattr(primitive, name)
            target.x, target.y, target.z = value
        else:
            setattr(primitive, name, value)


def _set_color(primitive: Any, rgba: tuple[float, float, float, float]) -> None:
    color = primitive.color
    color.r, color.g, color.b, color.a = rgba


def _glb_model(shape: Shape) -> dict[str, Any]:
    """The shape as an embedded binary glTF, its scale applied to the vertices, in the geometry's
    colour (Drake's colour is the geometry's, whatever the file's materials say)."""
    single = Scene((Link("mesh", 0, (Geometry(triangle_mesh(shape)),)),))
    data = write_gltf(single, binary=True)
    return {"data": data, "media_type": "model/gltf-binary", "scale": [1.0, 1.0, 1.0], "override_color": True}


def _triad_lines(shape: Shape) -> dict[str, Any]:
    """Three axes as a LINE_LIST from the origin, red x, green y, blue z (as meldis draws them)."""
    assert isinstance(shape, Triad)
    points, colors = [], []
    for axis in range(3):
        end = [0.0, 0.0, 0.0]
        end[axis] = shape.scale
        rgb = [0.0, 0.0, 0.0]
        rgb[axis] = 1.0
        for point in ([0.0, 0.0, 0.0], end):
            points.append({"x": point[0], "y": point[1], "z": point[2]})
            colors.append({"r": rgb[0], "g": rgb[1], "b": rgb[2], "a": 1.0})
    thickness = shape.tube if shape.tube > 0 else 0.01
    return {"type": LinePrimitive.LINE_LIST, "thickness": thickness, "points": points, "colors": colors}


def _polyline(shape: Shape) -> dict[str, Any]:
    assert isinstance(shape, Line)
    kind = LinePrimitive.LINE_LOOP if shape.closed else LinePrimitive.LINE_STRIP
    points = [{"x": x, "y": y, "z": z} for x, y, z in np.asarray(shape.points, dtype=np.float64).tolist()]
    return {"type": kind, "thickness": 2 * shape.radius if shape.radius > 0 else 0.01, "points": points}


TABLES = FormatTables("foxglove", {"glb_model": _glb_model, "triad_lines": _triad_lines, "polyline": _polyline})


# --- draw -> FrameTransforms ----------------------------------------------------------------------


def frame_transforms(poses: LinkPoses, stamp: tuple[int, int], frames: FrameNames) -> Any:
    """world -> every link as a FrameTransforms, built with the protobuf classes (the reference)."""
    message = FrameTransforms()
    rows = _transform_rows(poses).tolist()
    for name, (x, y, z, qx, qy, qz, qw) in zip(poses.names, rows, strict=True):
        transform = message.transforms.add(parent_frame_id=frames.world_frame, child_frame_id=frames(name))
        transform.timestamp.seconds, transform.timestamp.nanos = stamp
        translation, rotation = transform.translation, transform.rotation
        translation.x, translation.y, translation.z = x, y, z
        rotation.x, rotation.y, rotation.z, rotation.w = qx, qy, qz, qw
    return message


def _transform_rows(poses: LinkPoses) -> np.ndarray[Any, Any]:
    rows = np.empty((len(poses), 7), dtype="<f8")
    rows[:, :3] = poses.positions
    rows[:, 3:] = xyzw_from_wxyz(poses.quaternions_wxyz)
    return rows


def _timestamp(stamp: tuple[int, int]) -> bytes:
    """google.protobuf.Timestamp: seconds = 1, nanos = 2 (canonical: zeros left out)."""
    seconds, nanos = stamp
    out = b""
    if seconds:
        out += _key(1, 0) + _varint(seconds & 0xFFFFFFFFFFFFFFFF)
    if nanos:
        out += _key(2, 0) + _varint(nanos)
    return out


_DOUBLE = struct.Struct("<d")
# translation (field 4: Vector3 x=1 y=2 z=3) then rotation (field 5: Quaternion x=1 y=2 z=3 w=4),
# every double written: 67 bytes with the doubles at fixed places.
_POSE_BLOCK = _length_delimited(4, b"".join(_key(n, 1) + _DOUBLE.pack(0.0) for n in (1, 2, 3))) + (
    _length_delimited(5, b"".join(_key(n, 1) + _DOUBLE.pack(0.0) for n in (1, 2, 3, 4)))
)
_DOUBLE_PLACES = np.array([3, 12, 21, 32, 41, 50, 59], dtype=np.int64)


class FrameTransformsEncoder:
    """Link poses -> FrameTransforms bytes: world -> every link, one stamp, no message objects.

    Each FrameTransform is written parent, child, translation, rotation, then the timestamp (any
    field order parses alike), so the stamp sits at each entry's end. The layout is kept per set
    of link names and stamp length; a draw copies it and writes its doubles and stamp bytes.
    """

    def __init__(self, frames: FrameNames) -> None:
        self.frames = frames
        self._key: tuple[tuple[str, ...], int] | None = None
        self._template = b""
        self._double_bytes = np.zeros(0, dtype=np.int64)
        self._stamp_bytes = np.zeros(0, dtype=np.int64)

    def encode(self, poses: LinkPoses, stamp: tuple[int, int]) -> bytes:
        timestamp = _length_delimited(1, _timestamp(stamp))
        key = (poses.names, len(timestamp))
        if (
            self._key is None
            or key[1] != self._key[1]
            or (key[0] is not self._key[0] and key[0] != self._key[0])
        ):
            self._layout(poses.names, len(timestamp))
            self._key = key
        buffer = bytearray(self._template)
        view = np.frombuffer(buffer, dtype=np.uint8)
        view[self._double_bytes] = _transform_rows(poses).view(np.uint8).reshape(-1)
        view[self._stamp_bytes] = np.tile(np.frombuffer(timestamp, dtype=np.uint8), len(poses))
        return bytes(buffer)

    def _layout(self, names: tuple[str, ...], stamp_length: int) -> None:
        parent = _length_delimited(2, self.frames.world_frame.encode())
        chunks: list[bytes] = []
        doubles, stamps = [], []
        size = 0
        for name in names:
            body_head = parent + _length_delimited(3, self.frames(name).encode())
            body_length = len(body_head) + len(_POSE_BLOCK) + stamp_length
            head = _key(1, 2) + _varint(body_length) + body_head
            block_at = size + len(head)
            doubles.append(block_at + _DOUBLE_PLACES)
            stamps.append(block_at + len(_POSE_BLOCK) + np.arange(stamp_length))
            chunks += (head, _POSE_BLOCK, b"\0" * stamp_length)
            size += len(head) + len(_POSE_BLOCK) + stamp_length
        self._template = b"".join(chunks)
        places = np.asarray(doubles, dtype=np.int64).reshape(-1, 7)
        self._double_bytes = (places[:, :, None] + np.arange(8)).reshape(-1)
        self._stamp_bytes = np.asarray(stamps, dtype=np.int64).reshape(-1)


# --- schemas --------------------------------------------------------------------------------------


@cache
def schema(type_name: str) -> bytes:
    """A foxglove type's protobuf schema as Foxglove and MCAP carry it: a serialized
    FileDescriptorSet of its .proto file and everything that file imports."""
    from google.protobuf import descriptor_pb2, descriptor_pool
    from google.protobuf.descriptor import FileDescriptor

    importlib.import_module(f"foxglove_schemas_protobuf.{type_name.removeprefix('foxglove.')}_pb2")
    root = descriptor_pool.Default().FindMessageTypeByName(type_name).file
    files: dict[str, FileDescriptor] = {}

    def add(file: FileDescriptor) -> None:
        for dependency in file.dependencies:
            add(dependency)
        if file.name not in files:
            files[file.name] = file

    add(root)
    descriptor_set = descriptor_pb2.FileDescriptorSet()
    for file in files.values():
        file.CopyToProto(descriptor_set.file.add())
    return descriptor_set.SerializeToString()
