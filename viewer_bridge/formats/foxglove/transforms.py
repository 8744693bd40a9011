"""A draw as one `foxglove.FrameTransforms`: world -> each link frame, named as on ROS's /tf
(`viewer_bridge.formats.ros.tf.FrameNames`).

`FrameTransformsEncoder` writes the bytes straight from the draw arrays: the protobuf wire layout
per set of link names is a template (every field written, zeros too, which any parser reads as the
same message), and a draw scatters its doubles and its stamp into a copy.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from viewer_bridge.formats.protowire import key as _key
from viewer_bridge.formats.protowire import length_delimited as _length_delimited
from viewer_bridge.formats.protowire import varint as _varint
from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.model.pose_math import xyzw_from_wxyz
from viewer_bridge.model.scene import LinkPoses


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
        """The `foxglove.FrameTransforms` of `poses`, stamped `stamp` (sec, nanosec); it raises nothing
        of its own (the arrays are a decoded draw's)."""
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
