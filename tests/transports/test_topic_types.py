"""Which type a topic found in the graph is subscribed with (viewer_bridge/transports/topic_types.py),
the one rule of the ROS 2 and Zenoh transports: a named type takes topics of that type; `*` takes
topics of a generated LCM type's mapping, with its definition, and names any other type once."""

from __future__ import annotations

import logging

import pytest

from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.shared import Shared
from viewer_bridge.transports.base import CDR, MessageType
from viewer_bridge.transports.topic_types import TopicTypes

ANY = MessageType("*", CDR)
POSES = "geometry_msgs/msg/PoseArray"
COMMAND = "drake_lcm_msgs/msg/LcmtIiwaCommand"


@pytest.fixture(scope="module")
def types() -> TopicTypes:
    return TopicTypes(Shared(TypeLibrary.load()))


def test_a_named_type_takes_topics_of_that_type_only(types: TopicTypes) -> None:
    wanted = MessageType(POSES, CDR)
    assert types.pick(wanted, "/poses", [POSES]) is wanted
    assert types.pick(wanted, "/poses", [COMMAND]) is None


def test_any_type_takes_a_generated_lcm_type_with_its_definition(types: TopicTypes) -> None:
    found = types.pick(ANY, "/lcm_in/IIWA_COMMAND", [COMMAND])
    assert found == MessageType(COMMAND, CDR)
    assert found is not None and found.definition is not None
    assert found.definition.rihs01.startswith("RIHS01_") and "int32 num_joints" in found.definition.ros2msg


def test_any_type_leaves_other_types_alone_and_says_so_once(
    types: TopicTypes, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING, logger="viewer_bridge"):
        for _ in range(3):  # discovery asks every second
            assert types.pick(ANY, "/lcm_in/POSES", [POSES]) is None
    [record] = [r for r in caplog.records if "/lcm_in/POSES" in r.getMessage()]
    assert POSES in record.getMessage() and "no generated LCM type" in record.getMessage()


def test_every_type_takes_the_type_its_publishers_announce(types: TopicTypes) -> None:
    every = MessageType("**", CDR)
    assert types.pick(every, "/joint_states", ["sensor_msgs/msg/JointState"]) == MessageType(
        "sensor_msgs/msg/JointState", CDR
    )
    assert types.pick(every, "/nothing", []) is None
