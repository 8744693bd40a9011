"""`ros_topic_to_lcm` (viewer_bridge/translators/ros_topics.py): a topic's CDR as the LCM message of
its type's section-14 mapping; a type with no mapping, or no type, held."""

from __future__ import annotations

import pytest

from tests.lcmcodec.ros_bag import SAMPLES
from tests.lcmcodec.test_ros_cdr import serialized
from viewer_bridge.errors import DecodeError, Held
from viewer_bridge.lcmcodec.from_ros import map_ros_types
from viewer_bridge.lcmcodec.ros_types import InstalledDefinitions
from viewer_bridge.translators.ros_topics import RosTopicToLcm
from viewer_bridge.transports.base import CDR, MessageType, Received

JOINT_STATE = "sensor_msgs/msg/JointState"
JOINTS = next(message for _, ros_type, message in SAMPLES if ros_type == JOINT_STATE)


def received(data: bytes, ros_type: str | None) -> Received:
    return Received(
        "/joint_states", data, message_type=None if ros_type is None else MessageType(ros_type, CDR)
    )


def test_a_message_becomes_its_mapping_s_lcm_message_fingerprint_first() -> None:
    [(index, lcm)] = RosTopicToLcm().translate(received(serialized(JOINT_STATE, JOINTS), JOINT_STATE))
    assert index == 0
    assert lcm[:8] == map_ros_types(InstalledDefinitions(), [JOINT_STATE]).packed_fingerprint(JOINT_STATE)


def test_no_type_and_an_unmapped_type_are_held_and_bad_bytes_named() -> None:
    translator = RosTopicToLcm()
    with pytest.raises(Held) as untyped:
        translator.translate(received(b"\x00\x01\x00\x00", None))
    assert untyped.value.kind == "refused_type"
    with pytest.raises(Held) as unknown:
        translator.translate(received(b"\x00\x01\x00\x00", "lab_msgs/msg/Nowhere"))
    assert unknown.value.kind == "refused_type" and "lab_msgs/msg/Nowhere does not map onto LCM" in str(
        unknown.value
    )
    with pytest.raises(DecodeError, match=JOINT_STATE):
        translator.translate(received(serialized(JOINT_STATE, JOINTS)[:-9], JOINT_STATE))
