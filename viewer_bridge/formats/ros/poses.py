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
from viewer_bridge.formats.ros.cdr import CDR_LE, CDR_TIME, FRONT_PADDING, U32, cdr_string_4, time_parts
from viewer_bridge.formats.ros.message_types import POSE_ARRAY
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

    Layout (payload offsets after the 4-byte encapsulation header): stamp (int32 sec, uint32
    nanosec), frame_id string, pad to 4, uint32 count, pad to 8, then per pose 7 float64
    (position x y z, orientation x y z w). The bytes up to the count depend only on the frame id.
    The message is kept in one buffer per pose count: a draw writes its stamp and rows there and
    returns a copy. One encoder serves one thread at a time (a route's translations are serialised).
    """

    def __init__(self, frame_id: str = "world") -> None:
        """Made once per frame id: `EncodeError` when a CDR string cannot carry it (a NUL)."""
        self.frame_id = frame_id
        self._frame = cdr_string_4(frame_id, "header.frame_id")
        self._padding = b"\0" * (-(8 + len(self._frame) + 4) % 8)
        self._layout(0)

    def encode(self, poses: LinkPoses, stamp: tuple[int, int] | None = None) -> bytes:
        """The draw as a PoseArray stamped `stamp` (sec, nanosec), by default its sim time.

        Raises:
            EncodeError: a sim time past int32 seconds, which `builtin_interfaces/Time` cannot hold.
        """
        if len(poses) != len(self._rows):
            self._layout(len(poses))
        stamp_bytes = _stamp_bytes(poses.timestamp_ms) if stamp is None else CDR_TIME.pack(*stamp)
        self._buffer[FRONT_PADDING + 4 : FRONT_PADDING + 12] = stamp_bytes
        write_pose_rows_xyzw(self._rows, poses.positions, poses.quaternions_wxyz)
        return bytes(self._message)

    def _layout(self, count: int) -> None:
        head = b"".join((CDR_LE, bytes(8), self._frame, U32.pack(count), self._padding))
        self._buffer = bytearray(b"\0" * FRONT_PADDING + head + bytes(56 * count))
        self._message = memoryview(self._buffer)[FRONT_PADDING:]
        rows_at = FRONT_PADDING + len(head)
        self._rows = np.frombuffer(self._buffer, dtype="<f8", offset=rows_at).reshape(count, 7)


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
