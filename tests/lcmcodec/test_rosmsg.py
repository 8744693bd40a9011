"""The ROS 2 face of LCM types: .msg texts, ros2msg schemas, RIHS01 hashes, refusals."""

from __future__ import annotations

from typing import Any

import pytest

from tests.lcmcodec.corpus import CORPUS
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.lcmcodec.rosmsg import SCHEMA_SEPARATOR, map_to_ros
from viewer_bridge.lcmcodec.schema import parse_lcm


@pytest.fixture(scope="module")
def library() -> TypeLibrary:
    return TypeLibrary.load([str(CORPUS)])


def test_the_arm_state_definition(library: TypeLibrary) -> None:
    lines = library.get("lab.robot.arm_state_t").msg_definition.splitlines()
    assert lines[:3] == [
        "# An arm's state, as a lab might publish it: every primitive, arrays of",
        "# one to three dimensions sized by members and by constants, nested types.",
        "# LCM type lab.robot.arm_state_t",
    ]
    for line in [
        "int32 MAX_JOINTS=4", "int16 FLAG_MASK=31", "int16 NEGATIVE_ONE=-1", "float64 GAIN_SCALE=0.25",
        "float32 HALF=0.5", "int8 SMALL=-8", "int64 BIG=9223372036854775807",
        "int64 utime", "string robot_name", "int8 num_joints",
        "# joint angles, radians", "float64[] joint_angles",
        "float32[4] gains",  # fixed by a constant: T[N]
        "int32[] grid  # LCM int32_t grid[rows][cols]",  # flattened, with its shape in a comment
        "int16[] table  # LCM int16_t table[4][rows]",
        "uint8[] blob", "uint8[3] fixed_blob", "bool[] flags", "bool enabled",
        "lab_geometry_lcm_msgs/Point3dT tip", "lab_geometry_lcm_msgs/Point3dT[] waypoints",
        "lab_geometry_lcm_msgs/Point3dT[] corners  # LCM lab.geometry.point3d_t corners[2][2]",
        "float64 last_value",
    ]:  # fmt: skip
        assert line in lines, line
    assert lines.index("int8 num_joints") < lines.index("float64[] joint_angles")  # length fields stay, in order


def test_ros2msg_appends_each_nested_type_once(library: TypeLibrary) -> None:
    schema = library.get("drake.lcmt_robot_plan").ros2msg
    parts = schema.split(SCHEMA_SEPARATOR + "\n")
    assert parts[0].splitlines()[-1] == "drake_lcm_msgs/LcmtRobotState[] plan"
    assert parts[1].startswith("MSG: drake_lcm_msgs/LcmtRobotState\n")
    assert len(parts) == 2
    assert len(library.get("lab.robot.arm_state_t").ros2msg.split(SCHEMA_SEPARATOR)) == 2  # point3d once


def test_rihs01_agrees_with_rosbags(library: TypeLibrary) -> None:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    types: dict[str, Any] = {}
    for name, text in library.ros_definitions().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    for known in library.types():
        if known.ros_type is not None:
            assert known.rihs01 == store.hash_rihs01(known.ros_type)
            assert known.rihs01.startswith("RIHS01_") and len(known.rihs01) == 7 + 64
    # A hash covers the nested types: the plan's changes when the state's does.
    assert library.get("drake.lcmt_robot_plan").rihs01 != library.get("drake.lcmt_robot_state").rihs01


def test_types_that_collide_after_mapping_are_refused_naming_both() -> None:
    structs = {s.full_name: s for s in parse_lcm("package a; struct foo_bar { int8_t x; } struct fooBar { int8_t y; }")}
    mapping = map_to_ros(structs)
    assert not mapping.messages
    assert mapping.refused["a.foo_bar"] == mapping.refused["a.fooBar"] == (
        "a.fooBar and a.foo_bar both become a_lcm_msgs/msg/FooBar"
    )


def test_a_name_with_no_ros_form_refuses_its_type_and_those_nesting_it() -> None:
    text = "package p; struct bad_t { int8_t _; } struct user_t { bad_t b; } struct fine_t { int8_t ok; }"
    mapping = map_to_ros({s.full_name: s for s in parse_lcm(text)})
    assert mapping.refused["p.bad_t"] == "p.bad_t: field '_' has no valid ROS 2 name (got '')"
    assert mapping.refused["p.user_t"].startswith("it nests p.bad_t")
    assert list(mapping.messages) == ["p.fine_t"]
