"""The ROS 2 face of LCM types: .msg texts, ros2msg schemas, RIHS01 hashes, refusals."""

from __future__ import annotations

import re
from pathlib import Path
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
    assert lines[0] == "# LCM type lab.robot.arm_state_t"
    for line in [
        "int32 MAX_JOINTS=4", "int16 FLAG_MASK=31", "int16 NEGATIVE_ONE=-1", "float64 GAIN_SCALE=0.25",
        "float32 HALF=0.5", "int8 SMALL=-8", "int64 BIG=9223372036854775807",
        "int64 utime", "string robot_name", "int8 num_joints", "float64[] joint_angles",
        "float32[4] gains",  # fixed by a constant: T[N]
        "int32[] grid  # LCM int32_t grid[rows][cols]",  # flattened, with its shape in a comment
        "int16[] table  # LCM int16_t table[4][rows]",
        "uint8[] blob", "uint8[3] fixed_blob", "bool[] flags", "bool enabled",
        "lab_geometry_lcm_msgs/Point3dT tip", "lab_geometry_lcm_msgs/Point3dT[] waypoints",
        "lab_geometry_lcm_msgs/Point3dT[] corners  # LCM lab.geometry.point3d_t corners[2][2]",
        "float64 last_value",
    ]:  # fmt: skip
        assert line in lines, line
    # length fields stay, in order
    assert lines.index("int8 num_joints") < lines.index("float64[] joint_angles")


def test_the_msg_file_carries_the_lcm_comments_where_rosidl_reads_them(library: TypeLibrary) -> None:
    lines = library.get("lab.robot.arm_state_t").msg_file.splitlines()
    assert lines[:4] == [  # the file's comment block (rosidl: the message's), then a blank line
        "# An arm's state, as a lab might publish it: every primitive, arrays of",
        "# one to three dimensions sized by members and by constants, nested types.",
        "# LCM type lab.robot.arm_state_t",
        "",
    ]
    assert lines[lines.index("float64[] joint_angles") - 1] == "# joint angles, radians"
    assert library.get("lab.geometry.point3d_t").msg_file == (
        "# A point in a named frame.\n# Used by lab.robot's types, across packages.\n"
        "# LCM type lab.geometry.point3d_t\n\n"
        "float64 x\nfloat64 y\nfloat64 z\nstring frame_id  # the frame's name\n"
    )
    text = """package c;
/** A documented type.
 *  Second line. */
struct doc_t {
    // before the constant
    const int32_t MAX_N = 3;  // after the constant
    /** before n */
    int32_t n;  /* after n,
                   on two lines */
    // before the grid
    double grid[n][2];  // metres
    int8_t a, b;  // after both: the last one's
}
"""
    (struct,) = parse_lcm(text)
    message = map_to_ros({struct.full_name: struct}).messages["c.doc_t"]
    assert message.documented == (
        "# A documented type.\n# Second line.\n# LCM type c.doc_t\n\n"
        "# before the constant\nint32 MAX_N=3  # after the constant\n"
        "# before n\nint32 n  # after n,\n  # on two lines\n"
        "# before the grid\nfloat64[] grid  # LCM double grid[n][2]\n  # metres\n"
        "int8 a\nint8 b  # after both: the last one's\n"
    )
    assert message.definition == (
        "# LCM type c.doc_t\nint32 MAX_N=3\nint32 n\nfloat64[] grid  # LCM double grid[n][2]\nint8 a\nint8 b\n"
    )
    # rosidl's own parser (as mcap_ros2 vendors it) puts each comment on its field or constant.
    from mcap_ros2._vendor.rosidl_adapter.parser import parse_message_string

    spec = parse_message_string("c_lcm_msgs", "DocT", message.documented)
    assert spec.annotations["comment"] == ["A documented type.", "Second line.", "LCM type c.doc_t"]
    assert [(c.name, c.annotations["comment"]) for c in spec.constants] == [
        ("MAX_N", ["before the constant", "after the constant"])
    ]
    assert {f.name: f.annotations.get("comment") for f in spec.fields} == {
        "n": ["before n", "after n,", "on two lines"],
        "grid": ["before the grid", "LCM double grid[n][2]", "metres"],
        "a": [],
        "b": ["after both: the last one's"],
    }


def _without_comments(text: str) -> str:
    return re.sub(r"//[^\n]*|/\*.*?\*/", "", text, flags=re.DOTALL)


def test_comments_change_neither_the_announced_text_nor_the_type_hash(
    library: TypeLibrary, tmp_path: Path
) -> None:
    """What the bridge announces (ros2msg, RIHS01) and builds is the same with or without the .lcm
    comments; the workspace's .msg files differ only in comments, which RIHS01 leaves out (REP 2011)."""
    for path in CORPUS.rglob("*.lcm"):
        bare = tmp_path / path.relative_to(CORPUS)
        bare.parent.mkdir(parents=True, exist_ok=True)
        bare.write_text(_without_comments(path.read_text()))
    stripped = TypeLibrary.load([str(tmp_path)])
    assert stripped.ros_definitions() == library.ros_definitions()
    commented = library.get("lab.robot.arm_state_t")
    assert commented.msg_file != stripped.get("lab.robot.arm_state_t").msg_file
    for known in library.types():
        if known.ros_type is not None:
            bare_type = stripped.get(known.full_name)
            assert (known.ros2msg, known.rihs01) == (bare_type.ros2msg, bare_type.rihs01)
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    types: dict[str, Any] = {}
    for name, text in library.ros_definitions(comments=True).items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    for known in library.types():
        if known.ros_type is not None:
            assert store.hash_rihs01(known.ros_type) == known.rihs01, known.full_name


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
    structs = {
        s.full_name: s
        for s in parse_lcm("package a; struct foo_bar { int8_t x; } struct fooBar { int8_t y; }")
    }
    mapping = map_to_ros(structs)
    assert not mapping.messages
    assert (
        mapping.refused["a.foo_bar"]
        == mapping.refused["a.fooBar"]
        == ("a.fooBar and a.foo_bar both become a_lcm_msgs/msg/FooBar")
    )


def test_a_name_with_no_ros_form_refuses_its_type_and_those_nesting_it() -> None:
    text = "package p; struct bad_t { int8_t _; } struct user_t { bad_t b; } struct fine_t { int8_t ok; }"
    mapping = map_to_ros({s.full_name: s for s in parse_lcm(text)})
    assert mapping.refused["p.bad_t"] == "p.bad_t: field '_' has no valid ROS 2 name (got '')"
    assert mapping.refused["p.user_t"].startswith("it nests p.bad_t")
    assert list(mapping.messages) == ["p.fine_t"]
