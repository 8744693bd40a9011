"""Foxglove messages built with the protobuf classes: the references the fast encoders are held to."""

from __future__ import annotations

from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.model.pose_math import xyzw_from_wxyz
from viewer_bridge.model.scene import LinkPoses


def frame_transforms(poses: LinkPoses, stamp: tuple[int, int], frames: FrameNames) -> FrameTransforms:
    """world -> every link as a FrameTransforms, one field at a time."""
    message = FrameTransforms()
    quaternions = xyzw_from_wxyz(poses.quaternions_wxyz).tolist()
    for name, (x, y, z), (qx, qy, qz, qw) in zip(
        poses.names, poses.positions.tolist(), quaternions, strict=True
    ):
        transform = message.transforms.add(parent_frame_id=frames.world_frame, child_frame_id=frames(name))
        transform.timestamp.seconds, transform.timestamp.nanos = stamp
        transform.translation.x, transform.translation.y, transform.translation.z = x, y, z
        transform.rotation.x, transform.rotation.y, transform.rotation.z, transform.rotation.w = (
            qx,
            qy,
            qz,
            qw,
        )
    return message
