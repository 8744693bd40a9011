"""The protobuf-object reference for ign/gz poses: `Pose_V` and `PosesStamped` messages built
field by field. `viewer_bridge.formats.ign.poses.PosesEncoder` must write their bytes exactly; the
tests compare the two and bench/ign.py times them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.model.pose_math import xyzw_from_wxyz
from viewer_bridge.model.scene import LinkPoses
from viewer_bridge.model.sim_time import sec_nsec_from_ms


def _set_stamp(time: Any, timestamp_ms: int) -> None:
    time.sec, time.nsec = sec_nsec_from_ms(timestamp_ms)


def pose_v(poses: LinkPoses) -> Any:
    """A draw as `Pose_V`: one `Pose` per link, named with the link's Drake name, header stamped."""
    message = MESSAGES.Pose_V()
    _set_stamp(message.header.stamp, poses.timestamp_ms)
    _fill_poses(message.pose, poses)
    return message


def poses_stamped(poses: LinkPoses) -> Any:
    """The legacy `PosesStamped`: like `Pose_V`, with the sim time in `time` as well."""
    message = MESSAGES.PosesStamped()
    _set_stamp(message.header.stamp, poses.timestamp_ms)
    _set_stamp(message.time, poses.timestamp_ms)
    _fill_poses(message.pose, poses)
    return message


def _fill_poses(repeated: Any, poses: LinkPoses) -> None:
    values = np.concatenate((poses.positions, xyzw_from_wxyz(poses.quaternions_wxyz)), axis=1).tolist()
    for index, (name, (x, y, z, qx, qy, qz, qw)) in enumerate(zip(poses.names, values, strict=True)):
        pose = repeated.add(name=name, id=index)
        position, orientation = pose.position, pose.orientation
        position.x, position.y, position.z = x, y, z
        orientation.x, orientation.y, orientation.z, orientation.w = qx, qy, qz, qw


def xyz(vector: Any) -> list[float]:
    """A message's Vector3d as a list, to compare with the scene's values."""
    return [vector.x, vector.y, vector.z]
