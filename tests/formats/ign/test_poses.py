"""ign/gz `Pose_V` / `PosesStamped`, read back with protoc's classes for Debian's ign-msgs 8 files,
and the template encoder against the protobuf-object reference."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import Capture
from tests.formats.ign.oracle import pose_v, poses_stamped, xyz
from tests.strategies import link_poses
from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.ign.poses import PosesEncoder, poses_from_pose_v
from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.model.scene import LinkPoses

ROLES = ["ILLUSTRATION", "PROXIMITY"]


@pytest.mark.parametrize("role", ROLES)
def test_pose_v_read_by_debians_protos(
    drake_capture: dict[str, Capture], debian_ign_msgs: ModuleType, role: str
) -> None:
    poses = drake_capture[role].poses
    theirs = debian_ign_msgs.Pose_V.FromString(pose_v(poses).SerializeToString())
    assert theirs.header.stamp.sec * 1000 + theirs.header.stamp.nsec // 1_000_000 == poses.timestamp_ms
    assert [pose.name for pose in theirs.pose] == list(poses.names)
    for pose, position, (w, x, y, z) in zip(
        theirs.pose, poses.positions, poses.quaternions_wxyz, strict=True
    ):
        assert xyz(pose.position) == position.tolist()
        assert [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w] == [
            x,
            y,
            z,
            w,
        ]
    robot_nums = dict(zip(poses.names, poses.robot_nums.tolist(), strict=True))
    assert poses_from_pose_v(MESSAGES.parse("Pose_V", theirs.SerializeToString()), robot_nums) == LinkPoses(
        poses.timestamp_ms, poses.names, poses.robot_nums, poses.positions, poses.quaternions_wxyz
    )


@settings(max_examples=60, deadline=None)
@given(link_poses())
def test_draw_to_pose_v_to_draw_round_trips(poses: LinkPoses) -> None:
    robot_nums = dict(zip(poses.names, poses.robot_nums.tolist(), strict=True))
    for build in (pose_v, poses_stamped):
        message = build(poses)
        back = poses_from_pose_v(
            MESSAGES.parse(type(message).DESCRIPTOR.name, message.SerializeToString()), robot_nums
        )
        assert back.names == poses.names and back.timestamp_ms == poses.timestamp_ms
        np.testing.assert_array_equal(back.positions, poses.positions)
        np.testing.assert_allclose(back.quaternions_wxyz, poses.quaternions_wxyz, atol=1e-15)


def _oracle(poses: LinkPoses, message: str) -> bytes:
    """The protobuf-object path: the reference the template encoder must equal byte for byte."""
    build = pose_v if message == "Pose_V" else poses_stamped
    return bytes(build(poses).SerializeToString())


@settings(max_examples=80, deadline=None)
@given(st.lists(link_poses(max_links=5), min_size=1, max_size=4), st.sampled_from(["Pose_V", "PosesStamped"]))
def test_poses_encoder_writes_protobufs_bytes(frames: list[LinkPoses], message: str) -> None:
    """One encoder over several frames (names and zeros changing or not): protobuf's bytes each time."""
    encoder = PosesEncoder(message)
    for poses in frames:
        assert encoder.encode(poses) == _oracle(poses, message)


def test_poses_encoder_follows_zeros_and_signs_from_frame_to_frame() -> None:
    """+0.0 is left out and -0.0 written, as protobuf does; a value reaching or leaving 0 changes
    the layout; a negative or zero time leaves fields out as protobuf does."""
    encoder = PosesEncoder()
    names = ("plant::a", "plant::robot::b", "world_fixed")
    base = np.array([[0.5, -1.0, 2.0], [0.0, 0.0, 0.0], [1e-300, -0.0, 3.0]])
    quaternions = np.array([[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5], [0.0, -0.0, 1.0, 0.0]])
    for step, timestamp in enumerate([0, 1, 999, 1000, 1500, -1500, 2**40]):
        positions = base.copy()
        positions[0, 1] = 0.0 if step % 2 else -1.0  # a value reaching 0 and leaving it again
        poses = LinkPoses(timestamp, names, np.zeros(3, np.int32), positions, quaternions)
        assert encoder.encode(poses) == _oracle(poses, "Pose_V")
    assert encoder.encode(LinkPoses(5, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))) == (
        _oracle(LinkPoses(5, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4))), "Pose_V")
    )


@pytest.mark.parametrize("role", ROLES)
def test_poses_encoder_on_drakes_draws(
    drake_capture: dict[str, Capture], debian_ign_msgs: ModuleType, role: str
) -> None:
    """Drake's own draws, decoded on the fast path: protobuf's bytes, which Debian's protos read."""
    poses = DrawDecoder().decode(DrawEncoder().encode(drake_capture[role].poses))  # Drake's bytes
    assert poses.positions.dtype == np.float32  # the fast decoder's arrays, as the bridge has them
    encoded = PosesEncoder().encode(poses)
    assert encoded == _oracle(poses, "Pose_V")
    theirs = debian_ign_msgs.Pose_V.FromString(encoded)
    assert [pose.name for pose in theirs.pose] == list(poses.names)
