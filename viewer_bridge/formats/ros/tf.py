"""Drake's link poses as a ROS 2 TF tree: `tf2_msgs/msg/TFMessage` from the draw arrays.

Every link is a child of the world frame (Drake's draw gives world poses), named as every tool
in the field names Drake's frames: `plant::iiwa::iiwa_link_0` -> `plant/iiwa/iiwa_link_0`, after
an optional prefix that keeps the trees of several scenes (Drake's illustration, proximity and
perception roles) apart on one `/tf`. Drake's `world` link is the world frame itself.

`TransformsEncoder` writes the CDR straight from the arrays: the per-link layout (stamps,
frame names, where each transform's seven doubles sit) is a message written once per set of link
names by the generated writer, which marks where the stamps and transforms are; a draw writes
the stamps and the doubles there and returns a copy.
"""

from __future__ import annotations

import numpy as np

from viewer_bridge.formats.ros.cdr import CDR_TIME, POSE_ITEM, payload_items
from viewer_bridge.formats.ros.message_types import TF_MESSAGE, WORLD
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.pose_math import write_pose_rows_xyzw
from viewer_bridge.model.scene import LinkPoses, frame_name

_MARKS = ("transforms.header.stamp", "transforms.transform")
_ZERO = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))  # a transform, until a draw writes its own


class FrameNames:
    """TF frame names for Drake link names: `prefix` + `::` -> `/`; Drake's world is `world_frame`."""

    def __init__(self, world_frame: str = WORLD, prefix: str = "") -> None:
        self.world_frame = world_frame
        self.prefix = prefix

    def __call__(self, link_name: str) -> str:
        return self.world_frame if link_name == WORLD else self.prefix + frame_name(link_name)


class TransformsEncoder:
    """Link poses -> `TFMessage` CDR: `world_frame` -> every link, all with one stamp.

    The message is kept in one buffer per set of link names; a draw rewrites only its stamps and
    transforms there, and the bytes returned are a copy. One encoder serves one thread at a time
    (a route's translations are serialised).
    """

    def __init__(self, frames: FrameNames) -> None:
        self.frames = frames
        self._layout(())

    def encode(self, poses: LinkPoses, stamp: tuple[int, int]) -> bytes:
        """The `tf2_msgs/TFMessage` CDR of `poses`, stamped `stamp` (sec, nanosec).

        Raises:
            EncodeError: a frame name a CDR string cannot carry (a NUL, text that is no Unicode).
        """
        if poses.names is not self._names and poses.names != self._names:  # one tuple while they repeat
            self._layout(poses.names)
        write_pose_rows_xyzw(self._rows, poses.positions, poses.quaternions_wxyz)
        self._stamps[self._stamp_at] = np.frombuffer(CDR_TIME.pack(*stamp), _STAMP_ITEM)
        self._transforms[self._transform_at] = self._rows.view(POSE_ITEM).reshape(-1)
        return bytes(self._message)

    def _layout(self, names: tuple[str, ...]) -> None:
        parent = self.frames.world_frame
        transforms = [(((0, 0), parent), self.frames(name), _ZERO) for name in names]
        message, marks = ros_writer(TF_MESSAGE, _MARKS).write_marked((transforms,))
        self._message = bytearray(message)
        # Each stamp (8 bytes, 4-aligned in the payload) and each transform (56 bytes, 8-aligned)
        # is one item: one scatter of N items each, where a scatter of the 7N doubles costs
        # several times more.
        self._stamps = payload_items(self._message, _STAMP_ITEM, 4)
        self._transforms = payload_items(self._message, POSE_ITEM, 8)
        self._stamp_at = np.asarray(marks["transforms.header.stamp"], dtype=np.intp) // 4
        self._transform_at = np.asarray(marks["transforms.transform"], dtype=np.intp) // 8
        self._rows = np.empty((len(names), 7), dtype="<f8")
        self._names = names


_STAMP_ITEM = np.dtype((np.void, CDR_TIME.size))
