"""LCM names -> ROS 2 names, held to rosidl_adapter's own patterns."""

from __future__ import annotations

import contextlib
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from viewer_bridge.errors import NameRefused
from viewer_bridge.lcmcodec.rosnames import (
    constant_name,
    field_name,
    message_name,
    package_name,
    ros_topic_for_channel,
)

# rosidl_adapter's patterns, restated here to check the module against.
PACKAGE = re.compile(r"^(?!.*__)(?!.*_$)[a-z][a-z0-9_]*$")
MESSAGE = re.compile(r"^[A-Z][A-Za-z0-9]*$")
CONSTANT = re.compile(r"^[A-Z]([A-Z0-9_]?[A-Z0-9]+)*$")


@pytest.mark.parametrize(
    ("lcm", "ros"),
    [("drake", "drake_lcm_msgs"), ("exlcm", "exlcm_lcm_msgs"), ("lab.robot", "lab_robot_lcm_msgs"),
     ("myLab.armControl", "my_lab_arm_control_lcm_msgs"), ("", "lcm_msgs")],
)  # fmt: skip
def test_packages(lcm: str, ros: str) -> None:
    assert package_name(lcm) == ros


@pytest.mark.parametrize(
    ("lcm", "ros"),
    [("lcmt_iiwa_status", "LcmtIiwaStatus"), ("example_t", "ExampleT"), ("thingT", "ThingT"),
     ("point3d_t", "Point3dT"), ("lcmt__double", "LcmtDouble"), ("_hidden_t", "HiddenT")],
)  # fmt: skip
def test_messages(lcm: str, ros: str) -> None:
    assert message_name(lcm) == ros


@pytest.mark.parametrize(
    ("lcm", "ros"),
    [("jointAngles", "joint_angles"), ("num_joints", "num_joints"), ("robotName2D", "robot_name2_d"),
     ("HTTPServer", "httpserver"), ("_private", "private"), ("trailing_", "trailing"), ("a__b", "a_b"),
     ("utime", "utime"), ("x9Y", "x9_y")],
)  # fmt: skip
def test_fields(lcm: str, ros: str) -> None:
    assert field_name(lcm) == ros


@pytest.mark.parametrize(
    ("lcm", "ros"),
    [("maxJoints", "MAX_JOINTS"), ("BOX", "BOX"), ("FLAG_MASK", "FLAG_MASK"), ("negativeOne", "NEGATIVE_ONE"),
     ("_X_", "X")],
)  # fmt: skip
def test_constants(lcm: str, ros: str) -> None:
    assert constant_name(lcm) == ros


@pytest.mark.parametrize(
    ("convert", "name", "reason"),
    [(field_name, "_", "field '_' has no valid ROS 2 name"), (field_name, "_9lives", "got '9lives'"),
     (constant_name, "__", "constant '__'"), (message_name, "_3d_t", "got '3dT'"),
     (package_name, "_9x", "package '_9x'")],
)  # fmt: skip
def test_names_with_no_ros_form_are_refused_by_name(convert: object, name: str, reason: str) -> None:
    with pytest.raises(NameRefused, match=re.escape(reason)):
        convert(name)  # type: ignore[operator]


IDENTIFIERS = st.from_regex(r"\A[A-Za-z_][A-Za-z0-9_]{0,12}\Z")


@given(IDENTIFIERS)
def test_every_result_matches_rosidls_patterns(name: str) -> None:
    for convert, pattern in ((field_name, PACKAGE), (constant_name, CONSTANT), (message_name, MESSAGE),
                             (package_name, PACKAGE)):  # fmt: skip
        with contextlib.suppress(NameRefused):
            assert pattern.match(convert(name)), (convert, name)


def test_topics() -> None:
    assert ros_topic_for_channel("left-arm.status") == "/lcm/left_arm_status"
    assert ros_topic_for_channel("DRAKE_VIEWER_DRAW") == "/lcm/DRAKE_VIEWER_DRAW"
