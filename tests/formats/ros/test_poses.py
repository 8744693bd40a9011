"""Drake's draws as ROS 2 PoseArray / PoseStamped, and back, checked against real Drake traffic,
rclpy and rosbags."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import Capture
from tests.formats.ros import oracle as ros_oracle
from tests.optional import peer
from tests.strategies import link_poses
from viewer_bridge.errors import DecodeError, EncodeError, SceneError
from viewer_bridge.formats.ros.message_types import POSE_ARRAY
from viewer_bridge.formats.ros.messages import from_cdr, from_rclpy, to_cdr, to_rclpy
from viewer_bridge.formats.ros.poses import (
    PoseArrayEncoder,
    pose_array_arrays,
    pose_from_message,
    poses_from_pose_array_cdr,
)
from viewer_bridge.model.scene import LinkPoses, Pose

geometry = peer("geometry_msgs.msg")
serialization = peer("rclpy.serialization")

ROLES = ["ILLUSTRATION", "PROXIMITY"]


@pytest.mark.parametrize("role", ROLES)
def test_pose_array_fast_path_matches_the_objects(drake_capture: dict[str, Capture], role: str) -> None:
    poses = raw = drake_capture[role].poses  # from Drake's draw: w-first float32 values
    data = PoseArrayEncoder("world").encode(poses)
    objects = to_rclpy(ros_oracle.pose_array(poses))
    decoded = serialization.deserialize_message(data, geometry.PoseArray)
    assert decoded == objects
    assert to_rclpy(from_cdr(data, POSE_ARRAY)) == objects
    assert decoded.header.stamp.sec * 1000 + decoded.header.stamp.nanosec // 1_000_000 == poses.timestamp_ms
    for index, pose in enumerate(decoded.poses):
        w, x, y, z = raw.quaternions_wxyz[index]
        assert [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w] == [
            x,
            y,
            z,
            w,
        ]
        assert [pose.position.x, pose.position.y, pose.position.z] == raw.positions[index].tolist()
    for index, data in enumerate(ros_oracle.PoseStampedEncoder("world").encode(poses)):  # the fast path
        objects = to_rclpy(ros_oracle.pose_stamped(poses, index))
        assert serialization.deserialize_message(data, geometry.PoseStamped) == objects
        assert to_rclpy(from_cdr(data, ros_oracle.POSE_STAMPED)) == objects
        assert objects.pose.position.x == poses.positions[index][0]


@settings(max_examples=30, deadline=None)
@given(st.lists(link_poses(max_links=5), min_size=2, max_size=5))
def test_one_pose_array_encoder_follows_changing_draws(frames: list[LinkPoses]) -> None:
    """The encoder keeps its message between draws: nothing of one draw may show in the next."""
    encoder = PoseArrayEncoder("world")
    for poses in frames:
        expected = to_rclpy(ros_oracle.pose_array(poses))
        assert serialization.deserialize_message(encoder.encode(poses), geometry.PoseArray) == expected


@settings(max_examples=60, deadline=None)
@given(link_poses(), st.text(st.characters(exclude_characters="\0", exclude_categories=("Cs",)), max_size=9))
def test_draw_to_pose_array_to_draw_round_trips(poses: LinkPoses, frame_id: str) -> None:
    data = PoseArrayEncoder(frame_id).encode(poses)
    assert serialization.deserialize_message(data, geometry.PoseArray) == to_rclpy(
        ros_oracle.pose_array(poses, frame_id)
    )
    for index, stamped in enumerate(ros_oracle.PoseStampedEncoder(frame_id).encode(poses)):
        assert serialization.deserialize_message(stamped, geometry.PoseStamped) == to_rclpy(
            ros_oracle.pose_stamped(poses, index, frame_id)
        )
    names, numbers = poses.names, poses.robot_nums.tolist()
    rclpy_object = serialization.deserialize_message(data, geometry.PoseArray)
    for back in (
        poses_from_pose_array_cdr(data, names, numbers),
        ros_oracle.poses_from_pose_array(ros_oracle.pose_array(poses), names, numbers),
        ros_oracle.poses_from_pose_array(from_rclpy(rclpy_object), names, numbers),
    ):
        assert back.names == poses.names and back.robot_nums.tolist() == numbers
        assert back.timestamp_ms == poses.timestamp_ms
        np.testing.assert_array_equal(back.positions, poses.positions)
        np.testing.assert_allclose(back.quaternions_wxyz, poses.quaternions_wxyz, atol=1e-15)


def pose_array_with(orientation: list[float], count: int = 2) -> Any:
    message = ros_oracle.pose_array(
        LinkPoses(0, tuple(f"l{i}" for i in range(count)), np.zeros(count, np.int32), np.zeros((count, 3)),
                  np.tile([1.0, 0, 0, 0], (count, 1)))
    )  # fmt: skip
    q = message.poses[1].orientation
    q.x, q.y, q.z, q.w = orientation
    return message


@pytest.mark.parametrize(
    ("orientation", "reason"),
    [
        ([float("nan"), 0.0, 0.0, 1.0], r"poses\[1\]: quaternion of length nan"),
        ([0.0, 0.0, 0.0, 0.0], r"poses\[1\]: quaternion of length 0 is not a rotation"),
        ([0.0, 0.0, 0.0, 2.0], r"poses\[1\]: quaternion of length 2"),
    ],
)
def test_bad_quaternions_are_refused(orientation: list[float], reason: str) -> None:
    message = pose_array_with(orientation)
    with pytest.raises(SceneError, match=reason):
        ros_oracle.poses_from_pose_array(message, ["a", "b"])
    with pytest.raises(SceneError, match=reason):
        poses_from_pose_array_cdr(to_cdr(message), ["a", "b"])


def test_a_nearly_unit_quaternion_is_normalised() -> None:
    back = ros_oracle.poses_from_pose_array(pose_array_with([0.0, 0.0, 0.0, 1.004]), ["a", "b"])
    assert back.quaternions_wxyz[1].tolist() == [1.0, 0.0, 0.0, 0.0]


def test_a_frame_id_with_a_nul_is_refused() -> None:
    with pytest.raises(EncodeError, match=r"header.frame_id: .* contains a NUL"):
        PoseArrayEncoder("a\0b")
    with pytest.raises(EncodeError, match="not valid Unicode"):
        ros_oracle.PoseStampedEncoder("\ud800")


def test_pose_array_errors_name_what_is_wrong() -> None:
    data = to_cdr(pose_array_with([0.0, 0.0, 0.0, 1.0]))
    with pytest.raises(SceneError, match="2 poses but 1 link names"):
        poses_from_pose_array_cdr(data, ["a"])
    with pytest.raises(DecodeError, match="count 2 needs 112 bytes, 111 follow") as caught:
        pose_array_arrays(data[:-1])
    assert caught.value.field == "poses"
    with pytest.raises(DecodeError, match="not little-endian CDR"):
        pose_array_arrays(b"\x00\x00" + data[2:])
    huge = bytearray(data)
    huge[24:28] = (2**31).to_bytes(4, "little")  # the count claims 2^31 poses
    with pytest.raises(DecodeError, match="count 2147483648"):
        pose_array_arrays(bytes(huge))
    with pytest.raises(DecodeError, match="not a valid CDR message"):
        from_cdr(b"\x00\x01\x00\x00\xff", POSE_ARRAY)


def test_pose_stamped_reads_back_as_a_pose() -> None:
    poses = LinkPoses(
        2500, ("a",), np.zeros(1, np.int32), np.array([[1.0, 2.0, 3.0]]), np.array([[0.0, 0.0, 1.0, 0.0]])
    )
    stamped = from_cdr(to_cdr(ros_oracle.pose_stamped(poses, 0, "map")), ros_oracle.POSE_STAMPED)
    assert stamped.header.frame_id == "map" and (stamped.header.stamp.sec, stamped.header.stamp.nanosec) == (
        2,
        5 * 10**8,
    )
    assert pose_from_message(stamped.pose) == Pose((1.0, 2.0, 3.0), (0.0, 0.0, 1.0, 0.0))
    stamped.pose.position.y = float("nan")
    with pytest.raises(SceneError, match="pose.position is not finite"):
        pose_from_message(stamped.pose)
