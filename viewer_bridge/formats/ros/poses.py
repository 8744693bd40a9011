"""Drake's draw as a ROS 2 `geometry_msgs/PoseArray`, written and read straight from the arrays.

`PoseArrayEncoder`: draw -> PoseArray CDR, one buffer per pose count, no message per link;
`pose_array_arrays` and `poses_from_pose_array_cdr` read it back (PoseArray carries no link
names, so the caller gives them). Quaternion order is converted by `viewer_bridge.model.scene`
(`pose_rows_xyzw`, `link_poses_from_xyzw`).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.ros.cdr import CDR_TIME, FRONT_PADDING, time_parts
from viewer_bridge.formats.ros.message_types import POSE_ARRAY
from viewer_bridge.lcmcodec.codegen import CDR_LE
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.pose_math import write_pose_rows_xyzw
from viewer_bridge.model.scene import FloatArray, LinkPoses, Pose, link_poses_from_xyzw, pose_from_xyzw
from viewer_bridge.model.sim_time import ms_from_sec_nsec


def pose_from_message(message: Any, what: str = "pose") -> Pose:
    """A `geometry_msgs/Pose` as a scene pose (checked: see `scene.pose_from_xyzw`)."""
    p, q = message.position, message.orientation
    return pose_from_xyzw([p.x, p.y, p.z], [q.x, q.y, q.z, q.w], what)


def _stamp_bytes(timestamp_ms: int) -> bytes:
    return CDR_TIME.pack(*time_parts(timestamp_ms))


class PoseArrayEncoder:
    """draw arrays -> `geometry_msgs/PoseArray` CDR, without building a message per link.

    The message is written once per pose count by the generated writer, which marks where the
    stamp and the first pose are (per pose 7 float64: position x y z, orientation x y z w), into
    a buffer 4 bytes in, so that the poses are aligned for numpy: a draw writes its stamp and rows
    there and returns a copy. One encoder serves one thread at a time (a route's translations are
    serialised).
    """

    def __init__(self, frame_id: str = "world") -> None:
        """Made once per frame id: `EncodeError` when a CDR string cannot carry it (a NUL)."""
        self.frame_id = frame_id
        self._layout(0)

    def encode(self, poses: LinkPoses, stamp: tuple[int, int] | None = None) -> bytes:
        """The draw as a PoseArray stamped `stamp` (sec, nanosec), by default its sim time.

        Raises:
            EncodeError: a sim time past int32 seconds, which `builtin_interfaces/Time` cannot hold.
        """
        if len(poses) != len(self._rows):
            self._layout(len(poses))
        stamp_bytes = _stamp_bytes(poses.timestamp_ms) if stamp is None else CDR_TIME.pack(*stamp)
        self._buffer[self._stamp_at : self._stamp_at + CDR_TIME.size] = stamp_bytes
        write_pose_rows_xyzw(self._rows, poses.positions, poses.quaternions_wxyz)
        return bytes(self._message)

    def _layout(self, count: int) -> None:
        # The poses as tuples, so that the writer marks the first (an array would be one copy).
        poses = [((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))] * count
        message, marks = ros_writer(POSE_ARRAY, _MARKS).write_marked((((0, 0), self.frame_id), poses))
        front = FRONT_PADDING + len(CDR_LE)  # the buffer's index of payload offset 0
        self._buffer = bytearray(bytes(FRONT_PADDING) + message)
        self._message = memoryview(self._buffer)[FRONT_PADDING:]
        self._stamp_at = front + marks["header.stamp"][0]
        rows_at = front + (marks["poses.position"][0] if count else len(message) - len(CDR_LE))
        self._rows = np.frombuffer(self._buffer, dtype="<f8", count=7 * count, offset=rows_at).reshape(
            count, 7
        )


_MARKS = ("header.stamp", "poses.position")


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
    # An empty sequence is not aligned (as rosbags and Fast CDR write it); earlier versions of this
    # bridge padded it anyway: both are read.
    poses_at = _aligned(count_at + 4, 8) if count else count_at + 4
    if end - poses_at != 56 * count and not (count == 0 and end - poses_at < 8):
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
    """PoseArray CDR straight to link poses; PoseArray carries no names, so the caller gives them.

    Raises `DecodeError` for bytes that are not a PoseArray, `SceneError` when the counts differ
    or a pose is not finite or not a rotation.
    """
    timestamp_ms, _, positions, xyzw = pose_array_arrays(data)
    return link_poses_from_xyzw(timestamp_ms, names, robot_nums, positions, xyzw, "poses")


__all__ = [
    "PoseArrayEncoder",
    "pose_array_arrays",
    "pose_from_message",
    "poses_from_pose_array_cdr",
]
