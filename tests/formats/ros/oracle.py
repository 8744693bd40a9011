"""The ROS 2 messages as rosbags objects, built field by field: the slow, readable reference the
fast CDR paths of `viewer_bridge.formats.ros` are tested against (and benchmarked beside).

Also `PoseStampedEncoder`, a fast path no translator uses: bench/translators.py times it against
rclpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from viewer_bridge.formats.mappings import ShapeRule
from viewer_bridge.formats.ros.cdr import StampedTemplate, time_parts
from viewer_bridge.formats.ros.markers import (
    DELETE_ALL,
    MarkerSpec,
    marker_settings,
    marker_specs,
    world_poses,
)
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY, POSE_ARRAY, TF_MESSAGE
from viewer_bridge.formats.ros.messages import make
from viewer_bridge.formats.ros.tables import TABLES
from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.model.contact import ContactDrawOptions, ContactResults, contact_scene
from viewer_bridge.model.pose_math import pose_rows_xyzw
from viewer_bridge.model.scene import Geometry, LinkPoses, Pose, Scene, Shape, link_poses_from_xyzw
from viewer_bridge.model.sim_time import ms_from_sec_nsec
from viewer_bridge.model.skipped import per_geometry

ARROW, TRIANGLE_LIST, DELETEALL = 0, 11, 3  # visualization_msgs/Marker's type and action numbers

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
MARKER = "visualization_msgs/msg/Marker"


def time_message(timestamp_ms: int) -> Any:
    """A `builtin_interfaces/Time` for Drake's millisecond sim time."""
    seconds, nanoseconds = time_parts(timestamp_ms)
    return make("builtin_interfaces/msg/Time", sec=seconds, nanosec=nanoseconds)


def header(frame_id: str, timestamp_ms: int = 0) -> Any:
    return make("std_msgs/msg/Header", stamp=time_message(timestamp_ms), frame_id=frame_id)


def pose_message(pose: Pose) -> Any:
    x, y, z = pose.position
    qx, qy, qz, qw = pose.quaternion_xyzw
    return make(
        "geometry_msgs/msg/Pose",
        position=make("geometry_msgs/msg/Point", x=x, y=y, z=z),
        orientation=make("geometry_msgs/msg/Quaternion", x=qx, y=qy, z=qz, w=qw),
    )


def pose_array(poses: LinkPoses, frame_id: str = "world") -> Any:
    """Every link's pose as one `geometry_msgs/PoseArray`, in the draw's link order (the bytes:
    `poses.PoseArrayEncoder`)."""
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
    """A `PoseArray` back as link poses (`poses.poses_from_pose_array_cdr` from its bytes).

    Raises `SceneError` when the counts differ or a pose is not finite or not a rotation.
    """
    positions = [[p.position.x, p.position.y, p.position.z] for p in message.poses]
    xyzw = [[p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] for p in message.poses]
    time = message.header.stamp
    timestamp_ms = ms_from_sec_nsec(time.sec, time.nanosec)
    return link_poses_from_xyzw(timestamp_ms, names, robot_nums, positions, xyzw, "poses")


class PoseStampedEncoder:
    """draw arrays -> one `geometry_msgs/PoseStamped` CDR per link, in the draw's order.

    Everything before the pose (the stamp, the frame id) is the same for every link of a frame,
    and the pose is last: each message is that prefix plus 56 bytes of one row. The generated
    writer says where the stamp and the pose are.
    """

    def __init__(self, frame_id: str = "world") -> None:
        self.frame_id = frame_id
        origin = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))
        self._template = StampedTemplate(POSE_STAMPED, (((0, 0), frame_id), origin), ("pose",))

    def encode(self, poses: LinkPoses) -> list[bytes]:
        prefix = self._template.stamped(time_parts(poses.timestamp_ms))[: self._template.at["pose"]]
        return [prefix + row for row in map(bytes, pose_rows_xyzw(poses.positions, poses.quaternions_wxyz))]


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
    """Every geometry of the scene as a shape_msgs message in its link's frame (`shapes.shapes_cdr`
    writes the same messages' bytes).

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


def _shape_message(rule: ShapeRule, shape: Shape, target: str) -> Any:
    values = rule.values(shape, {})
    typename = rule.message or target
    if rule.type_code is not None:
        values["type"] = rule.type_code
    if typename == "shape_msgs/msg/Mesh":  # the table gives arrays: here, a message per point
        values["vertices"] = [
            make("geometry_msgs/msg/Point", x=x, y=y, z=z) for x, y, z in values["vertices"].tolist()
        ]
        values["triangles"] = [
            make("shape_msgs/msg/MeshTriangle", vertex_indices=np.asarray(row, dtype=np.uint32))
            for row in values["triangles"]
        ]
    return make(typename, **values)


def marker_array(scene: Scene, options: dict[str, Any] | None = None, delete_all: bool = True) -> Any:
    """The scene as a `visualization_msgs/MarkerArray` (rosbags message) in the world frame.

    Each marker's pose is its link's pose in `scene.poses` times the geometry's pose (a link
    missing from the poses, like `world`, sits at the origin). `options` override the table's
    (`frame_id`, `embed_mesh_files`). With `delete_all` the array starts with a DELETEALL marker,
    as a new load should, so that RViz forgets the previous scene. `marker_array_cdr` is the
    fast path to the same message's bytes.
    """
    frame_id = str(marker_settings(options)["frame_id"])
    specs = marker_specs(scene, options)
    positions, wxyz = world_poses(scene, specs)
    markers = [_marker_message(DELETE_ALL, frame_id, Pose())] if delete_all else []
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


def transforms_message(poses: LinkPoses, stamp: tuple[int, int], frames: FrameNames) -> Any:
    """`tf.TransformsEncoder`'s `TFMessage` as rosbags objects, built one transform at a time."""
    rows = pose_rows_xyzw(poses.positions, poses.quaternions_wxyz).tolist()
    transforms: Sequence[Any] = [
        make(
            "geometry_msgs/msg/TransformStamped",
            header=make(
                "std_msgs/msg/Header",
                stamp=make("builtin_interfaces/msg/Time", sec=stamp[0], nanosec=stamp[1]),
                frame_id=frames.world_frame,
            ),
            child_frame_id=frames(name),
            transform=make(
                "geometry_msgs/msg/Transform",
                translation=make("geometry_msgs/msg/Vector3", x=x, y=y, z=z),
                rotation=make("geometry_msgs/msg/Quaternion", x=qx, y=qy, z=qz, w=qw),
            ),
        )
        for name, (x, y, z, qx, qy, qz, qw) in zip(poses.names, rows, strict=True)
    ]
    return make(TF_MESSAGE, transforms=list(transforms))


def contact_marker_array(
    results: ContactResults, draw: ContactDrawOptions | None = None, markers: dict[str, Any] | None = None
) -> Any:
    """`contact.contact_marker_array_cdr`'s MarkerArray as a rosbags message."""
    return marker_array(contact_scene(results, draw), markers, delete_all=True)
