"""A scene to and from ign/gz `Model` (one model, a `Link` per Drake link) and `Model_V` (a
`Model` per robot_num, that is per Drake model instance).

A load is written by `model_bytes` / `model_v_bytes` from pieces (`_ModelWriter`), byte for byte
what protobuf writes for the message objects `model` / `model_v` build; those objects remain the
path for the values the pieces cannot write. `scene_from_model` reads either message back.
Which shape becomes which `Geometry` is in `mappings/ign.yaml` (`viewer_bridge.formats.ign.geometry`).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any

import numpy as np

from viewer_bridge.errors import SceneError
from viewer_bridge.formats import protowire as wire
from viewer_bridge.formats.ign.geometry import fill_geometry, geometry_message, shape_from_geometry
from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.model.pose_math import xyzw_from_wxyz
from viewer_bridge.model.scene import Geometry, Link, Pose, Scene, Shape, pose_from_xyzw
from viewer_bridge.model.skipped import per_geometry

_ROBOT_NUM = "robot_num"  # kept in each Link's header data so that robot_num survives the trip


def _set_pose(target: Any, pose: Pose) -> None:
    target.position.x, target.position.y, target.position.z = pose.position
    orientation = target.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = pose.quaternion_xyzw


def _fill_link(message: Any, link: Link, pose: Pose) -> None:
    message.name = link.name
    message.header.data.add(key=_ROBOT_NUM, value=[str(link.robot_num)])
    _set_pose(message.pose, pose)

    def visual(index: int, geometry: Geometry) -> Any:
        """The geometry's visual in a Link of its own: merged once it is made."""
        part = type(message)()
        visual = part.visual.add(name=f"{link.name}::visual_{index}", id=index, parent_name=link.name)
        _set_pose(visual.pose, geometry.pose)
        fill_geometry(visual.geometry, geometry.shape)
        diffuse = visual.material.diffuse  # float32 on the wire, as Drake's colour is
        diffuse.r, diffuse.g, diffuse.b, diffuse.a = geometry.color
        return part

    for part in per_geometry(link, visual):
        message.MergeFrom(part)


def model(scene: Scene, name: str = "drake") -> Any:
    """A load as one `Model` with a `Link` per Drake link and a `Visual` per geometry.

    Link poses are the scene's world poses (identity before the first draw); visual poses are
    in the link frame, as Drake's are.
    """
    message = MESSAGES.Model(name=name)
    _set_pose(message.pose, Pose())
    for link in scene.links:
        _fill_link(message.link.add(), link, scene.link_pose(link))
    return message


def model_bytes(scene: Scene, name: str = "drake") -> bytes:
    """`model(scene, name).SerializeToString()`, written from pieces instead of objects.

    A Model is its fields' encodings in field-number order, so it is written by concatenation:
    each distinct shape's `Geometry` is serialised once by protobuf, and poses and colours are
    packed here, leaving out zeros as proto3 does (by bit pattern: -0.0 is written). Filling a
    `Model` object field by field was most of a load's time.
    """
    try:
        return _model_payload(_ModelWriter(), scene, scene.links, name, 0)
    except OverflowError:  # a colour beyond float32: the object path writes it as protobuf does
        return bytes(model(scene, name).SerializeToString())


def model_v_bytes(scene: Scene) -> bytes:
    """`model_v(scene).SerializeToString()`, written as `model_bytes` writes a Model."""
    groups: dict[int, list[Link]] = {}
    for link in scene.links:
        groups.setdefault(link.robot_num, []).append(link)
    if any(not 0 <= robot_num < 2**32 for robot_num in groups):  # no uint32 id: as the object path refuses it
        return bytes(model_v(scene).SerializeToString())
    try:
        writer = _ModelWriter()
        return b"".join(
            wire.submessage(_MODELS, _model_payload(writer, scene, links, _model_name(links[0]), robot_num))
            for robot_num, links in groups.items()
        )
    except OverflowError:
        return bytes(model_v(scene).SerializeToString())


def _model_payload(
    writer: _ModelWriter, scene: Scene, links: Sequence[Link], name: str, model_id: int
) -> bytes:
    poses = _link_pose_values(scene, links)
    identity = wire.submessage(_MODEL_POSE, _pose_bytes(Pose()))
    head = (
        wire.string_field(_MODEL_NAME, name)
        + (_MODEL_ID + wire.varint(model_id) if model_id else b"")
        + identity
    )
    return head + b"".join(
        wire.submessage(_MODEL_LINK, writer.link(link, pose)) for link, pose in zip(links, poses, strict=True)
    )


# Field keys (docs/PROTOCOLS.md section 4): Model{name=2, id=3, pose=5, link=7}; Link{header=1, name=3,
# pose=10, visual=11}; Header{data=2}, its Map{key=1, value=2}; Visual{name=2, id=3,
# parent_name=4, pose=9, geometry=10, material=11}; Material{diffuse=6}; Color{r..a=2..5};
# Pose{position=4, orientation=5}; Vector3d{x..z=2..4}; Quaternion{x..w=2..5}.
_MODEL_NAME, _MODEL_ID, _MODEL_POSE, _MODEL_LINK = (
    wire.key(2, 2),
    wire.key(3, 0),
    wire.key(5, 2),
    wire.key(7, 2),
)
_MODELS = wire.key(2, 2)  # Model_V{models=2}
_LINK_HEADER, _LINK_NAME, _LINK_POSE, _LINK_VISUAL = (
    wire.key(1, 2),
    wire.key(3, 2),
    wire.key(10, 2),
    wire.key(11, 2),
)
_VISUAL_NAME, _VISUAL_ID, _VISUAL_PARENT = wire.key(2, 2), wire.key(3, 0), wire.key(4, 2)
_VISUAL_POSE, _VISUAL_GEOMETRY, _VISUAL_MATERIAL = wire.key(9, 2), wire.key(10, 2), wire.key(11, 2)
_DIFFUSE = wire.key(6, 2)
_FLOAT_KEYS = [wire.key(number, wire.FIXED32) for number in (2, 3, 4, 5)]
_FLOAT, _ZERO_FLOAT = struct.Struct("<f"), bytes(4)


_POSE = wire.PoseWriter(4, 5, 2)  # Pose{position=4, orientation=5}, their components from 2


def _link_pose_values(scene: Scene, links: Sequence[Link]) -> list[list[float]]:
    """Each link's world pose as x, y, z, qx, qy, qz, qw (`Scene.link_pose`, for all links at once)."""
    if scene.poses is None:
        return [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]] * len(links)
    count = len(scene.poses)
    values = np.zeros((count + 1, 7))
    values[count, 6] = 1.0  # the last row: identity, for links the frame lacks (e.g. world)
    values[:count, :3] = scene.poses.positions
    values[:count, 3:] = xyzw_from_wxyz(scene.poses.quaternions_wxyz)
    rows = [scene.poses.row_of(link.name) for link in links]
    chosen: list[list[float]] = values[[count if row is None else row for row in rows]].tolist()
    return chosen


def _pose_bytes(pose: Pose) -> bytes:
    return _pose_values_bytes([*pose.position, *pose.quaternion_xyzw])


def _pose_values_bytes(values: Sequence[float]) -> bytes:
    return _POSE.pose(*values)


def _material(color: Sequence[float]) -> bytes:
    """Material{diffuse}: float32 on the wire (OverflowError beyond float32's range)."""
    packed = [_FLOAT.pack(value) for value in color]
    diffuse = b"".join(
        key + data for key, data in zip(_FLOAT_KEYS, packed, strict=True) if data != _ZERO_FLOAT
    )
    return wire.submessage(_VISUAL_MATERIAL, wire.submessage(_DIFFUSE, diffuse))


class _ModelWriter:
    """The pieces of one Model: Geometry bytes per distinct shape, header bytes per robot_num."""

    def __init__(self) -> None:
        self.geometries: dict[int, tuple[Shape, bytes]] = {}  # by id: the scene's shapes, held here
        self.headers: dict[int, bytes] = {}
        # By `wire.exact_key`: 0.0 and -0.0 are equal floats but written differently.
        self.poses: dict[bytes, bytes] = {}  # geometry poses repeat (the same part on many links)
        self.colors: dict[bytes, bytes] = {}

    def link(self, link: Link, pose: Sequence[float]) -> bytes:
        header = self.headers.get(link.robot_num)
        if header is None:
            value = wire.submessage(wire.key(2, wire.LENGTH_DELIMITED), str(link.robot_num).encode())
            entry = wire.string_field(wire.key(1, wire.LENGTH_DELIMITED), _ROBOT_NUM) + value
            header = self.headers[link.robot_num] = wire.submessage(
                _LINK_HEADER, wire.submessage(wire.key(2, 2), entry)
            )
        parts = [
            header,
            wire.string_field(_LINK_NAME, link.name),
            wire.submessage(_LINK_POSE, _pose_values_bytes(pose)),
        ]
        parts += per_geometry(
            link,
            lambda index, geometry: wire.submessage(_LINK_VISUAL, self.visual(link.name, index, geometry)),
        )
        return b"".join(parts)

    def visual(self, link_name: str, index: int, geometry: Geometry) -> bytes:
        values = (*geometry.pose.position, *geometry.pose.quaternion_xyzw)
        pose_key = wire.exact_key(values)
        pose = self.poses.get(pose_key)
        if pose is None:
            pose = self.poses[pose_key] = wire.submessage(_VISUAL_POSE, _pose_values_bytes(values))
        color_key = wire.exact_key(geometry.color)
        material = self.colors.get(color_key)
        if material is None:
            material = self.colors[color_key] = _material(geometry.color)
        return b"".join((
            wire.string_field(_VISUAL_NAME, f"{link_name}::visual_{index}"),
            _VISUAL_ID + wire.varint(index) if index else b"",
            wire.string_field(_VISUAL_PARENT, link_name),
            pose,
            wire.submessage(_VISUAL_GEOMETRY, self.geometry(geometry.shape)),
            material,
        ))  # fmt: skip

    def geometry(self, shape: Shape) -> bytes:
        known = self.geometries.get(id(shape))
        if known is None:
            known = self.geometries[id(shape)] = (shape, bytes(geometry_message(shape).SerializeToString()))
        return known[1]


def model_v(scene: Scene) -> Any:
    """A load as `Model_V`: one `Model` per robot_num (model instance), id = robot_num."""
    message = MESSAGES.Model_V()
    by_robot: dict[int, Any] = {}
    for link in scene.links:
        if link.robot_num not in by_robot:
            by_robot[link.robot_num] = message.models.add(name=_model_name(link), id=link.robot_num)
            _set_pose(by_robot[link.robot_num].pose, Pose())
        _fill_link(by_robot[link.robot_num].link.add(), link, scene.link_pose(link))
    return message


def _model_name(link: Link) -> str:
    """`plant::iiwa::iiwa_link_0` -> `plant::iiwa`: the source and model instance part."""
    parts = link.name.split("::")
    return "::".join(parts[:-1]) if len(parts) > 1 else link.name


def scene_from_model(message: Any) -> Scene:
    """A `Model` or `Model_V` back as a scene (the reverse of `model` / `model_v`).

    Raises `SceneError` naming the link and visual whose geometry or pose makes no shape.
    """
    models: Sequence[Any] = message.models if hasattr(message, "models") else [message]
    links = []
    for model_message in models:
        for link in model_message.link:
            geometries = []
            for index, visual in enumerate(link.visual):
                where = f"link {link.name!r} visual {index}"
                try:
                    shape = shape_from_geometry(visual.geometry)
                except SceneError as error:
                    raise SceneError(f"{where}: {error}") from None
                color = visual.material.diffuse
                pose = _pose_from(visual.pose, where)
                geometries.append(Geometry(shape, pose, (color.r, color.g, color.b, color.a)))
            links.append(Link(link.name, _robot_num(link, model_message), tuple(geometries)))
    return Scene(tuple(links))


def _robot_num(link: Any, model_message: Any) -> int:
    for entry in link.header.data:
        if entry.key == _ROBOT_NUM and entry.value:
            try:
                return int(entry.value[0])
            except ValueError:
                break
    return int(model_message.id)


def _pose_from(message: Any, what: str) -> Pose:
    p, q = message.position, message.orientation
    return pose_from_xyzw([p.x, p.y, p.z], [q.x, q.y, q.z, q.w], what)


__all__ = [
    "model",
    "model_bytes",
    "model_v",
    "model_v_bytes",
    "scene_from_model",
]
