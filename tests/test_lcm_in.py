"""ROS 2 -> LCM for any known LCM type, end to end with real peers (the default configs' `lcm_in`
route: /lcm_in/<channel> -> <channel>, `ros_to_lcm`): an rclpy node over DDS and an rmw_zenoh
node over Zenoh publish each type of the outward tests' corpus (a lab's types: arrays sized by
fields, a two-dimensional one, strings, bytes, nested types of another package; Drake's driver
types), built by hand from lcm-gen's messages; the LCM side gets lcm-gen's own bytes and values.
A pydrake `LcmSubscriberSystem` receives a command a ROS node sent. Bad CDR is counted, named,
and never reaches LCM."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import pytest
from rclpy.serialization import serialize_message

from tests.conftest import lcm_url, read_line
from tests.peers import BridgeProcess, RosProbe, wait_for
from tests.test_router import LcmRecorder
from tests.translators.test_lcm_generic import CORPUS, arm_status, flat, lcmgen_corpus, snake
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.ros_build import interfaces as ros_interfaces
from viewer_bridge.transports.ros2 import message_class

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
__all__ = ["lcmgen_corpus"]  # a fixture, used by name

_NESTED = re.compile(r"(?:sequence<)?([a-z0-9_]+)/([A-Za-z0-9]+)")
LAB_PACKAGES = ["vbtest_geo_lcm_msgs", "vbtest_lab_lcm_msgs"]
DRAKE_SUBSCRIBER_SCRIPT = Path(__file__).parent / "drake_iiwa_command.py"


@pytest.fixture(scope="module")
def corpus_interfaces() -> TypeLibrary:
    """The corpus's interface packages built into the venv (kept; rebuilt only when they change),
    so that this test's rclpy node can publish them. Only these: drake_lcm_msgs is the project's."""
    library = TypeLibrary.load([str(CORPUS)])
    ros_interfaces.build(library.ros_definitions(), log=print, only=LAB_PACKAGES)
    return library


def ros_from_lcm(lcm: Any, ros_class: Any) -> Any:
    """The rclpy message with lcm-gen's message's values, written by hand as a ROS node would:
    snake_case names, multi-dimensional arrays flattened row-major, nested types by their class."""
    ros = ros_class()
    fields = ros_class.get_fields_and_field_types()
    cls = type(lcm)
    for name, typename, dims in zip(cls.__slots__, cls.__typenames__, cls.__dimensions__, strict=True):
        field, value = snake(name), getattr(lcm, name)
        if dims:
            value = flat(value, len(dims))
        if "." in typename:
            match = _NESTED.match(fields[field])
            assert match is not None, fields[field]
            nested = message_class(f"{match.group(1)}/msg/{match.group(2)}")
            value = [ros_from_lcm(item, nested) for item in value] if dims else ros_from_lcm(value, nested)
        setattr(ros, field, value)
    return ros


def iiwa_command(utime: int, joints: int = 7) -> Any:
    command = drake_lcmtypes.lcmt_iiwa_command()
    command.utime, command.num_joints = utime, joints
    command.joint_position = [0.125 * joint - 0.5 for joint in range(joints)]
    command.num_torques, command.joint_torque = 2, [1.5, -2.25]
    return command


def robot_plan() -> Any:
    plan = drake_lcmtypes.lcmt_robot_plan()
    plan.utime, plan.num_states = 77, 2
    for index in range(2):
        state = drake_lcmtypes.lcmt_robot_state()
        state.utime, state.num_joints = index, 2
        state.joint_name, state.joint_position = ["iiwa_joint_1", "iiwa_joint_ü"], [0.5 * index, -1.0]
        plan.plan.append(state)
    return plan


def corpus_messages(classes: dict[str, type]) -> dict[str, Any]:
    """lcm-gen messages of every kind the corpus has, by the channel each is sent on."""
    point = classes["vbtest_geo.point3_t"]()
    point.x, point.y, point.z = 1.0, -2.5, 1e-300
    return {
        "ARM_STATUS": arm_status(classes),
        "TOOL_POINT": point,
        "IIWA_COMMAND": iiwa_command(1_700_000_000_000_001),
        "ROBOT_PLAN": robot_plan(),
    }


def ros_type_of(library: TypeLibrary, message: Any) -> str:
    lcm_type = library.for_data(message.encode())
    assert lcm_type is not None and lcm_type.ros_type is not None
    return lcm_type.ros_type


def assert_lcm_got(recorder: LcmRecorder, sent: dict[str, Any], repeated: bool = False) -> None:
    """Each channel got exactly the one message (or, `repeated`, one or more copies of it), byte
    for byte lcm-gen's, decoding to its values."""
    for channel, message in sent.items():
        received = recorder.messages.get(channel, [])
        assert len(received) >= 1 if repeated else len(received) == 1, (channel, len(received))
        for data in received:
            assert data == message.encode(), channel  # the fingerprint, and every field as lcm-gen writes it
            assert type(message).decode(data).encode() == message.encode()


# Every channel these tests command, and an age limit no loaded machine reaches: freshness is
# tested on its own (tests/router/test_commands.py), a late command here would be a flake.
COMMANDS_ALLOWED = ("--allow-commands", ".*", "--set", "commands.max_age_ms=60000")


@pytest.fixture
def stats(tmp_path: Path) -> Path:
    return tmp_path / "stats.json"


def route_stats(path: Path, route: str) -> dict[str, Any]:
    try:
        return dict(json.loads(path.read_text())["routes"][route])
    except (OSError, ValueError, KeyError):
        return {}


# --- DDS ---------------------------------------------------------------------------------------------


def test_rclpy_commands_reach_lcm_as_lcm_gen_writes_them_and_bad_cdr_is_counted_and_named(
    corpus_interfaces: TypeLibrary, lcmgen_corpus: dict[str, type], stats: Path
) -> None:
    url = lcm_url(71)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(
        "--lcm-url", url, "--lcm-types", str(CORPUS), "--stats-json", str(stats), "--stats-period", "0.5",
        *COMMANDS_ALLOWED,
    )  # fmt: skip
    probe = RosProbe("lcm_in_commander")
    try:
        bridge.wait_for_line(" running (")
        sent = corpus_messages(lcmgen_corpus)
        # The outward route copies what the bridge sends on IIWA_COMMAND to /lcm/IIWA_COMMAND: the
        # loop guard lets that copy through (another name), as it would any node's command.
        copies = probe.subscribe("/lcm/IIWA_COMMAND", "drake_lcm_msgs/msg/LcmtIiwaCommand")
        publishers = {}
        for channel, message in sent.items():
            typename = ros_type_of(corpus_interfaces, message)
            publishers[channel] = probe.publisher(f"/lcm_in/{channel}", typename)
        # The bridge finds each topic in the graph (once a second) and subscribes with its type.
        assert probe.wait_for(lambda: all(p.get_subscription_count() >= 1 for p in publishers.values()), 90)
        for channel, message in sent.items():
            publishers[channel].publish(
                ros_from_lcm(message, message_class(ros_type_of(corpus_interfaces, message)))
            )
        recorder.sync()
        assert wait_for(lambda: all(channel in recorder.messages for channel in sent), 60), bridge.lines[-10:]
        recorder.sync()
        assert_lcm_got(recorder, sent)
        # lazy: sent once it sees the probe
        assert probe.wait_for(lambda: len(copies) >= 1, 60), bridge.lines[-10:]
        assert copies[0].utime == sent["IIWA_COMMAND"].utime

        # Bad CDR on the same topic (rclpy publishes bytes as they are): short, too long, and a
        # length field that disagrees with its sequence. Each is counted and named; none is sent.
        good = iiwa_command(2)
        cdr = serialize_message(ros_from_lcm(good, message_class("drake_lcm_msgs/msg/LcmtIiwaCommand")))
        wrong_length = iiwa_command(3)
        wrong_length.num_joints = 5  # the sequence holds 7
        bad = [
            cdr[:-5],
            cdr + bytes(16),
            serialize_message(
                ros_from_lcm(wrong_length, message_class("drake_lcm_msgs/msg/LcmtIiwaCommand"))
            ),
        ]

        def errors() -> int:
            return int(route_stats(stats, "lcm_in").get("errors", {}).get("DecodeError", 0))

        # one at a time: the route keeps the newest per channel
        for count, payload in enumerate(bad, start=1):
            publishers["IIWA_COMMAND"].publish(payload)
            assert wait_for(lambda count=count: errors() >= count, 60), (
                route_stats(stats, "lcm_in"),
                bridge.lines[-10:],
            )
        assert route_stats(stats, "lcm_in")["errors"] == {"DecodeError": 3}
        named = "\n".join(line for line in bridge.lines if "DecodeError" in line)
        assert "num_joints" in named or "joint_position" in named, named
        publishers["IIWA_COMMAND"].publish(cdr)  # the next good message flows
        assert wait_for(lambda: len(recorder.messages["IIWA_COMMAND"]) == 2, 60)
        recorder.sync()
        assert recorder.messages["IIWA_COMMAND"] == [sent["IIWA_COMMAND"].encode(), good.encode()]
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def test_a_topic_of_another_type_under_lcm_in_is_said_once_and_not_subscribed() -> None:
    url = lcm_url(72)
    # Allowed: a topic whose channel is not allowed is never looked at (test_commands.py).
    bridge = BridgeProcess("--lcm-url", url, "--allow-commands", "NOT_LCM")
    probe = RosProbe("lcm_in_stranger")
    try:
        bridge.wait_for_line(" running (")
        probe.publisher("/lcm_in/NOT_LCM", "geometry_msgs/msg/PoseArray")
        line = bridge.wait_for_line("/lcm_in/NOT_LCM", timeout=60)
        assert "geometry_msgs/msg/PoseArray" in line and "no generated LCM type" in line
        assert probe.node.count_subscribers("/lcm_in/NOT_LCM") == 0
    finally:
        probe.close()
        assert bridge.stop() == 0
    assert sum("/lcm_in/NOT_LCM" in line for line in bridge.lines) == 1  # said once, not every second


# --- Drake ------------------------------------------------------------------------------------------


def test_a_drake_lcm_subscriber_system_receives_a_command_a_ros_node_published() -> None:
    url = lcm_url(73)
    bridge = BridgeProcess(
        "--lcm-url", url, "--allow-commands", "IIWA_COMMAND", "--set", "commands.max_age_ms=60000"
    )
    probe = RosProbe("lcm_in_iiwa_planner")
    drake = subprocess.Popen(
        [sys.executable, str(DRAKE_SUBSCRIBER_SCRIPT), url, "120"], stdout=subprocess.PIPE, text=True
    )
    try:
        bridge.wait_for_line(" running (")
        assert drake.stdout is not None
        assert read_line(drake.stdout, "'listening' from the Drake subscriber").strip() == "listening"
        publisher = probe.publisher("/lcm_in/IIWA_COMMAND", "drake_lcm_msgs/msg/LcmtIiwaCommand")
        assert probe.wait_for(lambda: publisher.get_subscription_count() >= 1, 90)
        command = iiwa_command(123_456)
        publisher.publish(ros_from_lcm(command, message_class("drake_lcm_msgs/msg/LcmtIiwaCommand")))
        received = json.loads(read_line(drake.stdout, "the command the Drake subscriber received", 90))
        assert drake.wait(timeout=60) == 0
    finally:
        if drake.poll() is None:
            drake.kill()
        probe.close()
        assert bridge.stop() == 0
    assert received == {
        "utime": 123_456,
        "num_joints": 7,
        "joint_position": list(command.joint_position),
        "num_torques": 2,
        "joint_torque": [1.5, -2.25],
    }


# --- Zenoh -----------------------------------------------------------------------------------------


@pytest.fixture
def zenoh_router() -> Iterator[Any]:
    from tests.zenoh_peers import Router

    router = Router()
    yield router
    router.close()


def test_an_rmw_zenoh_node_commands_lcm_over_zenoh(
    zenoh_router: Any, corpus_interfaces: TypeLibrary, lcmgen_corpus: dict[str, type]
) -> None:
    """The rmw_zenoh-format peer publishes with its liveliness token (type name and RIHS01 hash,
    computed by rosbags from the type's definition): the zenoh config's `lcm_in` finds it and
    LCM gets lcm-gen's bytes. The CDR comes from rclpy's own serializer of the built interfaces."""
    from tests.zenoh_peers import RmwZenohPeer, rihs01

    library = corpus_interfaces
    url = lcm_url(74)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(
        "-c", "builtin:zenoh", "--lcm-url", url, "--lcm-types", str(CORPUS),
        "--set", f"zenoh.connect=[{zenoh_router.endpoint}]", "--set", "zenoh.domain_id=42", *COMMANDS_ALLOWED,
    )  # fmt: skip
    peer = RmwZenohPeer(zenoh_router.endpoint, 42, node="lcm_in_peer")
    try:
        bridge.wait_for_line(" running (")
        sent = corpus_messages(lcmgen_corpus)
        definitions = library.ros_definitions()
        publishers = {}
        for entity, (channel, message) in enumerate(sent.items(), start=1):
            typename = ros_type_of(library, message)
            publishers[channel] = peer.publisher(
                f"/lcm_in/{channel}", typename, entity=entity, type_hash=rihs01(typename, definitions)
            )
        # The bridge finds each publisher's token (once a second) and subscribes, announcing its own.
        assert wait_for(lambda: all(peer.subscribed(f"/lcm_in/{channel}") for channel in sent), 90), (
            bridge.lines[-10:]
        )
        payloads = {
            channel: serialize_message(ros_from_lcm(message, message_class(ros_type_of(library, message))))
            for channel, message in sent.items()
        }

        def arrived() -> bool:
            """Sends what has not arrived yet, as a controller repeats its command: the token that
            says the bridge subscribed may reach the peer before its subscription reaches the router."""
            missing = [channel for channel in sent if channel not in recorder.messages]
            for channel in missing:
                publishers[channel](payloads[channel])
            return not missing

        assert wait_for(arrived, 60), bridge.lines[-10:]  # resent every 50 ms until it arrives
        recorder.sync()
        assert_lcm_got(recorder, sent, repeated=True)
    finally:
        peer.close()
        assert bridge.stop() == 0
        recorder.close()
