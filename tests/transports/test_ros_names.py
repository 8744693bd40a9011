"""ROS 2 name rules as the config check applies them, held to rclpy's own checks (rcl and rmw)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import rclpy
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.context import Context
from rclpy.exceptions import InvalidNamespaceException, InvalidNodeNameException, InvalidTopicNameException
from rclpy.expand_topic_name import expand_topic_name
from rclpy.node import Node
from rclpy.validate_full_topic_name import validate_full_topic_name
from rclpy.validate_namespace import validate_namespace
from rclpy.validate_node_name import validate_node_name
from rclpy.validate_topic_name import validate_topic_name

from viewer_bridge.transports.ros_names import (
    namespace_problem,
    node_name_problem,
    ros_argument_problem,
    topic_problem,
)

TOPICS = [
    "/tf", "drake/markers", "/sim2/bad topic!", "a/", "/", "", "/a//b", "~", "~/a", "~a", "a/~", "1a", "a/1b",
    "/a_1/b_2", "{node}/x", "{1x}", "a{b", "a}b", "{a-b}", "/drake/proximity/shapes", "ü", "a.b", "_a", "/__x",
]  # fmt: skip
NAMESPACES = ["", "/", "/sim1", "sim1", "sim1/a", "/sim1/", "/a//b", "/1a", "1a", "/a-b", "/a_b/c"]
NODES = ["viewer_bridge", "", "9x", "viewer-bridge", "a b", "_x", "ünder"]


def rclpy_accepts_topic(name: str) -> bool:
    """What rclpy does with a topic name when a publisher is made: check, expand, check in full."""
    try:
        validate_topic_name(name)
        validate_full_topic_name(expand_topic_name(name, "viewer_bridge", "/ns"))
    except (InvalidTopicNameException, ValueError):  # ValueError: an unknown {substitution}
        return False
    return True


def accepted(check: object, name: str, refused: type[Exception]) -> bool:
    try:
        check(name)  # type: ignore[operator]
    except refused:
        return False
    return True


@pytest.mark.parametrize("name", TOPICS)
def test_topic_names_as_rclpy_judges_them(name: str) -> None:
    assert (topic_problem(name) is None) == rclpy_accepts_topic(name), topic_problem(name)


@given(st.text(alphabet="a1_/~{} !nodes", max_size=10))
@settings(max_examples=500, deadline=None)
def test_any_topic_name_as_rclpy_judges_it(name: str) -> None:
    assert (topic_problem(name) is None) == rclpy_accepts_topic(name), topic_problem(name)


@pytest.fixture(scope="module")
def context() -> Iterator[Context]:
    context = Context()
    rclpy.init(context=context)
    yield context
    rclpy.shutdown(context=context)


def node_made(context: Context, name: str, namespace: str) -> bool:
    """Whether rclpy makes a node of this name in this namespace (what the ros transport does)."""
    try:
        node = Node(name, namespace=namespace, context=context)
    except (InvalidNamespaceException, InvalidNodeNameException):
        return False
    node.destroy_node()
    return True


@pytest.mark.parametrize("namespace", NAMESPACES)
def test_namespaces_as_rclpy_judges_them(context: Context, namespace: str) -> None:
    expected = node_made(context, "viewer_bridge", namespace)
    assert expected == accepted(validate_namespace, "/" + namespace.lstrip("/"), InvalidNamespaceException)
    assert (namespace_problem(namespace) is None) == expected, namespace_problem(namespace)


@pytest.mark.parametrize("node", NODES)
def test_node_names_as_rclpy_judges_them(context: Context, node: str) -> None:
    expected = node_made(context, node, "")
    assert expected == accepted(validate_node_name, node, InvalidNodeNameException)
    assert (node_name_problem(node) is None) == expected, node_name_problem(node)


ROS_ARGUMENTS = [
    ("-r", "__ns:=/sim1"), ("-r", "__ns:=sim1"), ("-r", "__ns:=bad-ns"), ("-r", "__ns:=/a//b"), ("-r", "__ns:="),
    ("-r", "__node:=my-node"), ("-r", "__node:=my_node"), ("-r", "__name:=9x"), ("-r", "viewer_bridge:__ns:=/x"),
    ("-r", "/a:=/b"), ("-r", "a-b:=c"), ("-r", "/a:=b c"), ("-r", "n:/a:=/b"), ("-r", "no_rule"),
    ("-p", "use_sim_time:=maybe"), ("-p", "use_sim_time:=true"), ("-p", "use_sim_time:=On"),
    ("-p", "use_sim_time:=1"), ("-p", "use_sim_time:=FALSE"), ("-p", "x-y:=3"), ("-p", "a.b:=3"), ("-p", "a:=anything"),
]  # fmt: skip


def rcl_accepts(flag: str, value: str) -> bool:
    """Whether rclpy starts a node with these arguments (rcl parses them; the node declares use_sim_time)."""
    context = Context()
    try:
        rclpy.init(context=context, args=["viewer-bridge", "--ros-args", flag, value])
        Node("probe", context=context).destroy_node()
    except Exception:
        return False
    finally:
        if context.ok():
            rclpy.shutdown(context=context)
    return True


@pytest.mark.parametrize(("flag", "value"), ROS_ARGUMENTS)
def test_ros_arguments_are_refused_as_rcl_refuses_them(flag: str, value: str) -> None:
    problem = ros_argument_problem(flag, value)
    assert (problem is None) == rcl_accepts(flag, value), problem


def test_channel_names_give_one_channel_per_token_and_stay_bounded() -> None:
    import pytest

    from viewer_bridge.errors import Held
    from viewer_bridge.transports.ros_names import ChannelNames

    names = ChannelNames(limit=3)
    assert [names.token(channel) for channel in ("A.B", "1ARM", "A.B")] == ["A_B", "n1ARM", "A_B"]
    with pytest.raises(Held) as refused:  # a second channel with the token of the first: never merged
        names.token("A-B")
    assert refused.value.kind == "name_collision"
    assert str(refused.value) == (
        "LCM channels A.B and A-B both become the ROS name A_B: A-B is not carried (A.B, seen first, keeps it; "
        "rename one of them)"
    )
    with pytest.raises(Held, match="LCM channels A.B and A_B both"):  # the token's own name too
        names.token("A_B")
    assert names.channel("A_B") == "A.B" and names.channel("n1ARM") == "1ARM"
    assert names.channel("IIWA_COMMAND") == "IIWA_COMMAND"  # unseen: the token stands for itself
    assert names.token("C.D") == "C_D"  # the third, and the last remembered
    assert names.token("E_F") == "E_F"  # past the limit: a name that is a token already is carried
    with pytest.raises(Held) as full:  # but none that would be renamed: it could merge unseen
        names.token("G.H")
    assert full.value.kind == "too_many_channels" and "G.H would be renamed G_H" in str(full.value)
    with pytest.raises(Held, match="LCM channels C.D and C-D both"):
        names.token("C-D")
