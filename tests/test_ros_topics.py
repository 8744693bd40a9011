"""Live ROS 2 topics onto LCM (`viewer-bridge run --ros-topics REGEX`), end to end with real peers:
an rclpy node over DDS and an rmw_zenoh-format node over Zenoh publish `sensor_msgs/JointState`
and a custom type built by colcon (`vbtest_lcm_msgs/msg/JointSample`: fixed and unbounded arrays,
strings, bools, nested types of another package); lcm-gen's own Python, generated from the `.lcm`
files `lcm-types generate --ros-types` writes, decodes what reaches LCM to the published values.
Nothing is carried without the flag, a topic the bridge publishes itself is not carried back, and
two topics for one channel keep the first."""

from __future__ import annotations

import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rclpy.serialization import serialize_message

from tests.conftest import SYNC_CHANNEL
from tests.lcmcodec.ros_bag import lcmgen_decode
from tests.lcmcodec.test_from_ros import lcm_gen_all
from tests.peers import BridgeProcess, RosProbe, wait_for, write_config
from tests.ros_interfaces_corpus import BASE, DEFINITIONS, MAIN
from tests.test_router import LcmRecorder
from tests.zenoh_peers import free_lcm_url, stats_flags, stats_of
from viewer_bridge.cli.main import main
from viewer_bridge.ros_build import interfaces as ros_interfaces
from viewer_bridge.transports.ros2 import message_class

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

JOINT_STATE = "sensor_msgs/msg/JointState"
SAMPLE = f"{MAIN}/msg/JointSample"
SHARE = Path(sys.prefix) / "share"
_NESTED = re.compile(r"(?:sequence<)?([a-z0-9_]+)/([A-Za-z0-9]+)(?:\[\d+\])?>?")

# Values each field of the LCM side must give back exactly: float32s exactly representable, a
# uint8[] with 0 and 255, a non-ASCII string, an empty float64 sequence (as many JointState
# publishers leave velocity), negative and extreme integers.
JOINTS: dict[str, Any] = {
    "header": {"stamp": {"sec": 1_700_000_000, "nanosec": 123_456_789}, "frame_id": "base_link"},
    "name": ["shoulder", "elbow", "wrïst"],
    "position": [0.1, -1.2, 3.0],
    "velocity": [],
    "effort": [1e-9, 2.5, -7.0],
}
# rclpy's `serialize_message` (the Zenoh peer's CDR) pads an empty float64 sequence with 4 bytes
# more than it writes (docs/PROTOCOLS.md section 14), which the bridge refuses as trailing bytes:
# a full velocity there.
ZENOH_JOINTS = {**JOINTS, "velocity": [0.0, 0.5, -0.5]}
POINT = {"x": 1.0, "y": -2.5, "z": 1e-300}
JOINT_SAMPLE: dict[str, Any] = {
    "utime": 1_700_000_000_000_001,
    "num_joints": 7,
    "position_fixed": [0.125 * joint - 0.5 for joint in range(7)],
    "velocity": [0.25, -0.5],
    "torque": [1.5, -2.25, 0.0],
    "joint_names": ["j1", "jö2"],
    "flags": [-32768, 0, 32767],
    "ok": True,
    "tip": POINT,
    "path": [POINT, {"x": 0.0, "y": 0.0, "z": -1.0}],
    "ends": [{"x": 1.0, "y": 2.0, "z": 3.0}, POINT],
    "blob": {"name": "b", "kind": 1, "size": 3, "data": b"\x00\xff\x07", "valid": True},
}


@pytest.fixture(scope="module")
def custom_interfaces() -> None:
    """The corpus's interface packages built into the venv by colcon (kept; nothing to do when built)."""
    ros_interfaces.build(DEFINITIONS, log=print)


@pytest.fixture(scope="module")
def lcmgen_python(tmp_path_factory: pytest.TempPathFactory, custom_interfaces: None) -> Path:
    """lcm-gen's Python of the `.lcm` files `lcm-types generate --ros-types` writes for both types
    (the custom one from its installed package's `.msg` files)."""
    folder = tmp_path_factory.mktemp("ros_topics_types")
    sources = [JOINT_STATE, str(SHARE / MAIN / "msg"), str(SHARE / BASE / "msg")]
    assert main(["lcm-types", "generate", "--ros-types", *sources, "-o", str(folder / "lcm")]) == 0
    done = lcm_gen_all(folder / "lcm", folder / "gen")
    assert done.returncode == 0, done.stderr
    return folder / "gen" / "py"


def ros_message(typename: str, values: dict[str, Any]) -> Any:
    """The rclpy message of `typename` with `values` (nested dicts), as a node fills it."""
    cls = message_class(typename)
    message = cls()
    for field, value in values.items():
        field_type = cls.get_fields_and_field_types()[field]
        nested = _NESTED.fullmatch(field_type) if "/" in field_type else None
        if nested is not None:
            nested_type = f"{nested.group(1)}/msg/{nested.group(2)}"
            many = isinstance(value, list)
            value = (
                [ros_message(nested_type, item) for item in value]
                if many
                else ros_message(nested_type, value)
            )
        elif field_type.startswith("sequence<uint8") or field_type.startswith("uint8["):
            value = bytes(value)
        setattr(message, field, value)
    return message


def without_lengths(decoded: Any) -> Any:
    """lcm-gen's decoded message (nested dicts) without the length fields LCM adds (`x_length`),
    each checked against its array first."""
    if isinstance(decoded, list):
        return [without_lengths(item) for item in decoded]
    if not isinstance(decoded, dict):
        return decoded
    for name in [name for name in decoded if name.endswith("_length")]:
        assert decoded[name] == len(decoded[name.removesuffix("_length")]), name
    return {name: without_lengths(value) for name, value in decoded.items() if not name.endswith("_length")}


def assert_decodes_to_published(
    lcmgen_python: Path, joint_state: bytes, sample: bytes, joints: dict[str, Any] = JOINTS
) -> None:
    decoded = lcmgen_decode(
        lcmgen_python, [("sensor_msgs.JointState", joint_state), (f"{MAIN}.JointSample", sample)]
    )
    assert without_lengths(decoded[0]) == joints
    assert without_lengths(decoded[1]) == JOINT_SAMPLE


# --- DDS ---------------------------------------------------------------------------------------------


def test_rclpy_topics_reach_lcm_as_lcm_gen_reads_them_and_only_those_named(
    lcmgen_python: Path, tmp_path: Path
) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(
        "--lcm-url", url, "--ros-topics", "/joint_states", "--ros-topics", "/lab/.*", *stats_flags(stats)
    )  # fmt: skip
    probe = RosProbe("ros_topics_publisher")
    try:
        bridge.wait_for_line(" running (")
        bridge.wait_for_line("ros_topics: /joint_states | /lab/.* from ros onto LCM")  # said at start
        joints = probe.publisher("/joint_states", JOINT_STATE)
        sample = probe.publisher("/lab/sample", SAMPLE)
        other = probe.publisher("/joint_states_other", JOINT_STATE)  # matches no pattern in full
        # The bridge finds each topic in the graph (once a second) and subscribes with its type.
        assert probe.wait_for(
            lambda: joints.get_subscription_count() >= 1 and sample.get_subscription_count() >= 1, 90
        )
        for publisher, typename, values in [(joints, JOINT_STATE, JOINTS), (sample, SAMPLE, JOINT_SAMPLE),
                                            (other, JOINT_STATE, JOINTS)]:  # fmt: skip
            publisher.publish(ros_message(typename, values))
        assert wait_for(lambda: {"joint_states", "lab/sample"} <= recorder.messages.keys(), 60), bridge.lines[
            -10:
        ]
        recorder.sync()
        assert_decodes_to_published(
            lcmgen_python, recorder.messages["joint_states"][0], recorder.messages["lab/sample"][0]
        )
        assert len(recorder.messages["joint_states"]) == 1 and len(recorder.messages["lab/sample"]) == 1
        assert "joint_states_other" not in recorder.messages
        assert other.get_subscription_count() == 0  # looked at every second, never taken
        assert wait_for(lambda: stats_of(stats).get("ros_topics_ros", {}).get("messages_out") == 2, 30)
        # lcm_bus hears what the bridge itself wrote on LCM: its own message, not a type to add.
        held = lambda: stats_of(stats).get("lcm_bus", {}).get("held", {})  # noqa: E731
        assert wait_for(lambda: "joint_states" in held(), 30), bridge.lines[-10:]
        assert set(held()["joint_states"]) == set(held()["lab/sample"]) == {"own_message"}, held()
        unknown = [
            line for line in bridge.lines if "names no known LCM type" in line and SYNC_CHANNEL not in line
        ]
        assert not unknown, unknown
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def test_without_the_flag_nothing_is_carried(tmp_path: Path) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--lcm-url", url, "--allow-commands", "IIWA_COMMAND", *stats_flags(stats))
    probe = RosProbe("ros_topics_unnamed")
    try:
        bridge.wait_for_line(" running (")
        joints = probe.publisher("/joint_states", JOINT_STATE)
        # What the bridge does subscribe to it subscribes within seconds: /lcm_in/IIWA_COMMAND is
        # taken (an LCM type's topic, its channel allowed), /joint_states never.
        command = probe.publisher("/lcm_in/IIWA_COMMAND", "drake_lcm_msgs/msg/LcmtIiwaCommand")
        assert probe.wait_for(lambda: command.get_subscription_count() >= 1, 90)
        assert wait_for(lambda: bool(stats_of(stats)), 30)
        joints.publish(ros_message(JOINT_STATE, JOINTS))
        recorder.sync()
        assert joints.get_subscription_count() == 0
        assert not any(name.startswith("ros_topics") for name in stats_of(stats))
        assert "joint_states" not in recorder.messages
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def test_topics_the_bridge_publishes_are_not_carried_back(tmp_path: Path) -> None:
    """`--ros-topics '.*'` with the default config: the bridge's own /lcm/IIWA_STATUS (LCM -> ROS 2,
    lazy: made live by the probe's subscription, which puts the topic in the graph before the
    bridge publishes there) is never taken, nor /rosout and /parameter_events (which its node
    publishes too), so LCM gets no `lcm/...` channel; another node's topic is carried as usual."""
    import drake as drake_lcmtypes
    import lcm

    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--lcm-url", url, "--ros-topics", ".*", *stats_flags(stats))
    probe = RosProbe("ros_topics_loop")
    bus = lcm.LCM(url)
    status = drake_lcmtypes.lcmt_iiwa_status()
    status.utime, status.num_joints, status.joint_position_measured = 5, 1, [0.5]
    status.joint_velocity_estimated, status.joint_position_commanded, status.joint_position_ipo = (
        [0.0],
        [0.5],
        [0.5],
    )
    status.joint_torque_measured, status.joint_torque_commanded, status.joint_torque_external = (
        [1.0],
        [1.0],
        [0.0],
    )
    try:
        bridge.wait_for_line(" running (")
        copies = probe.subscribe("/lcm/IIWA_STATUS", "drake_lcm_msgs/msg/LcmtIiwaStatus")

        def copied() -> bool:
            bus.publish("IIWA_STATUS", status.encode())  # until the lazy route's copies arrive
            return len(copies) > 0

        assert wait_for(copied, 90), bridge.lines[-10:]
        # Found after the bridge's own publisher: a discovery pass has seen both.
        joints = probe.publisher("/joint_states", JOINT_STATE)
        assert probe.wait_for(lambda: joints.get_subscription_count() >= 1, 90)
        joints.publish(ros_message(JOINT_STATE, JOINTS))
        assert wait_for(lambda: "joint_states" in recorder.messages, 60), bridge.lines[-10:]
        bus.publish("IIWA_STATUS", status.encode())
        count = len(copies)
        assert wait_for(lambda: len(copies) > count, 60)  # what the bridge publishes after that, too
        recorder.sync()
        carried = {name for name in recorder.messages if name not in ("IIWA_STATUS", "LCM_SELF_TEST")}
        assert carried == {"joint_states", SYNC_CHANNEL}, carried
        assert probe.node.count_subscribers("/lcm/IIWA_STATUS") == 1  # the probe's alone
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


# --- Zenoh -----------------------------------------------------------------------------------------


@pytest.fixture
def zenoh_router() -> Iterator[Any]:
    from tests.zenoh_peers import Router

    router = Router()
    yield router
    router.close()


def test_an_rmw_zenoh_node_s_topics_reach_lcm(zenoh_router: Any, lcmgen_python: Path) -> None:
    """The rmw_zenoh-format peer publishes with its liveliness tokens (type name and RIHS01 hash:
    the custom type's computed by rosbags from its definitions); the bridge subscribes with the
    announced hash. The CDR comes from rclpy's serializer."""
    from tests.zenoh_peers import RmwZenohPeer, rihs01

    url = free_lcm_url()
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(
        "-c", "builtin:zenoh", "--lcm-url", url, "--ros-topics", "/joint_states|/lab/sample",
        "--set", f"zenoh.connect=[{zenoh_router.endpoint}]", "--set", "zenoh.domain_id=43",
    )  # fmt: skip
    peer = RmwZenohPeer(zenoh_router.endpoint, 43, node="ros_topics_peer")
    try:
        bridge.wait_for_line(" running (")
        joints = peer.publisher("/joint_states", JOINT_STATE, entity=1)
        sample = peer.publisher("/lab/sample", SAMPLE, entity=2, type_hash=rihs01(SAMPLE, DEFINITIONS))
        payloads = {
            "joint_states": (joints, bytes(serialize_message(ros_message(JOINT_STATE, ZENOH_JOINTS)))),
            "lab/sample": (sample, bytes(serialize_message(ros_message(SAMPLE, JOINT_SAMPLE)))),
        }
        assert wait_for(lambda: peer.subscribed("/joint_states") and peer.subscribed("/lab/sample"), 90), (
            bridge.lines[-10:]
        )

        def arrived() -> bool:
            """Sends what has not arrived yet: the token that says the bridge subscribed may reach
            the peer before its subscription reaches the router."""
            missing = [channel for channel in payloads if channel not in recorder.messages]
            for channel in missing:
                publish, data = payloads[channel]
                publish(data)
            return not missing

        assert wait_for(arrived, 60), bridge.lines[-10:]
        recorder.sync()
        messages = recorder.messages
        assert_decodes_to_published(
            lcmgen_python, messages["joint_states"][0], messages["lab/sample"][0], ZENOH_JOINTS
        )
    finally:
        peer.close()
        assert bridge.stop() == 0
        recorder.close()


# --- one channel, two topics -----------------------------------------------------------------------

BOTH_GRAPHS = """\
ros_topics: ["/dup"]
zenoh: {{connect: ["{endpoint}"], domain_id: 44}}
routes:  # routes that make the config use both ROS graphs: ros_topics reads from each
  - name: to_dds
    source: {{transport: lcm, name: UNUSED_A}}
    translator: lcm_to_ros
    destination: {{transport: ros, name: /unused_a}}
  - name: to_zenoh
    source: {{transport: lcm, name: UNUSED_B}}
    translator: lcm_to_ros
    destination: {{transport: zenoh, name: /unused_b}}
"""


def test_a_channel_two_topics_map_to_keeps_the_first_and_says_so_once(
    zenoh_router: Any, tmp_path: Path
) -> None:
    """/dup over DDS and /dup over Zenoh both map to LCM `dup`: the one carried first keeps it, the
    other is held (`channel_taken`), counted, and named with the first in one line."""
    from tests.zenoh_peers import RmwZenohPeer

    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    config = write_config(tmp_path, BOTH_GRAPHS.format(endpoint=zenoh_router.endpoint))
    bridge = BridgeProcess("-c", str(config), "--lcm-url", url, *stats_flags(stats))
    probe = RosProbe("ros_topics_dds_dup")
    peer = RmwZenohPeer(zenoh_router.endpoint, 44, node="ros_topics_zenoh_dup")
    try:
        bridge.wait_for_line(" running (")
        dds = probe.publisher("/dup", JOINT_STATE)
        assert probe.wait_for(lambda: dds.get_subscription_count() >= 1, 90)
        dds.publish(ros_message(JOINT_STATE, JOINTS))
        assert wait_for(lambda: "dup" in recorder.messages, 60), bridge.lines[-10:]
        first = recorder.messages["dup"][0]
        zenoh = peer.publisher("/dup", JOINT_STATE, entity=1)
        assert wait_for(lambda: peer.subscribed("/dup"), 90), bridge.lines[-10:]
        data = bytes(serialize_message(ros_message(JOINT_STATE, ZENOH_JOINTS)))

        def held() -> int:
            counts = stats_of(stats).get("ros_topics_zenoh", {}).get("held", {})
            return int(counts.get("/dup", {}).get("channel_taken", 0))

        def refused_twice() -> bool:
            zenoh(data)  # resent: the bridge's subscription may reach the router after its token
            return held() >= 2

        assert wait_for(refused_twice, 60), bridge.lines[-10:]
        dds.publish(ros_message(JOINT_STATE, JOINTS))  # the first topic goes on
        assert wait_for(lambda: len(recorder.messages["dup"]) >= 2, 60)
        recorder.sync()
        assert set(recorder.messages["dup"]) == {first}  # never the Zenoh topic's message
        lines = [line for line in bridge.lines if "channel_taken" in line and "counted" in line]
        assert len(lines) == 1, lines  # said once, however many are held
        assert "lcm dup carries /dup (from ros) already: /dup (from zenoh) is not carried there" in lines[0]
    finally:
        peer.close()
        probe.close()
        assert bridge.stop() == 0
        recorder.close()
