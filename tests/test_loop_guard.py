"""The loop guard (viewer_bridge/router/echoes.py) with real transports: a bridge that carries
channels both ways on the same names (LCM LOOP_* -> ROS 2 /LOOP_* by `lcm_to_ros`, and ROS 2
/LOOP_* -> LCM LOOP_* by `ros_to_lcm`), over DDS and over Zenoh, passes one message in as
exactly one out, each way, and counts its own message coming back (held: `own_message`) instead of sending it round again.
The channels name their type (`lcmt_iiwa_command` shares its fingerprint with
`lcmt_allegro_command`: the channel's name picks)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import lcm
import pytest
from rclpy.serialization import deserialize_message, serialize_message

from tests.conftest import lcm_url
from tests.peers import BridgeProcess, RosProbe, wait_for, write_config
from tests.test_lcm_in import ros_from_lcm
from tests.test_router import LcmRecorder
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.transports.ros2 import message_class

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

BOTH_WAYS = """\
commands: {{allow: ["LOOP_.*"], max_age_ms: 60000}}
routes:
  - name: out
    source: {{transport: lcm, name: "(LOOP_.*)"}}
    translator: lcm_to_ros
    destination: {{transport: {ros}, name: "/{{1}}"}}
    qos: {{depth: 100, durability: transient_local}}
    rate: {{policy: all}}
  - name: back
    source: {{transport: {ros}, name: "/(LOOP_.*)"}}
    translator: ros_to_lcm
    destination: {{transport: lcm, name: "{{1}}"}}
    qos: {{depth: 100}}
    rate: {{policy: all}}
"""
COMMAND = "drake_lcm_msgs/msg/LcmtIiwaCommand"
A, B = "LOOP_IIWA_COMMAND_A", "LOOP_IIWA_COMMAND_B"


def command(utime: int) -> Any:
    message = drake_lcmtypes.lcmt_iiwa_command()
    message.utime, message.num_joints, message.joint_position = utime, 2, [0.5, -0.25]
    message.num_torques, message.joint_torque = 0, []
    return message


def cdr(utime: int) -> bytes:
    return bytes(serialize_message(ros_from_lcm(command(utime), message_class(COMMAND))))


class DdsSide:
    """The ROS 2 side over DDS: an rclpy node."""

    transport = "ros"

    def __init__(self) -> None:
        self.probe = RosProbe("loop_probe")

    def bridge_args(self) -> list[str]:
        return []

    def subscribe(self, topic: str, latched: bool = False) -> Callable[[], list[int]]:
        messages = self.probe.subscribe(topic, COMMAND, latched=latched)
        return lambda: [message.utime for message in list(messages)]

    def publisher(self, topic: str) -> Callable[[bytes], None]:
        return self.probe.publisher(topic, COMMAND).publish  # type: ignore[no-any-return]

    def bridge_subscribed(self, topic: str) -> bool:
        return self.probe.node.count_subscribers(topic) >= 2  # the probe's and the bridge's

    def close(self) -> None:
        self.probe.close()


class ZenohSide:
    """The ROS 2 side over Zenoh: an rmw_zenoh-format node and a router, both in this process."""

    transport = "zenoh"

    def __init__(self) -> None:
        from tests.zenoh_peers import RmwZenohPeer, Router, rihs01

        self.router = Router()
        self.peer = RmwZenohPeer(self.router.endpoint, 42, node="loop_probe")
        self.hash = rihs01(COMMAND, TypeLibrary.load().ros_definitions())

    def bridge_args(self) -> list[str]:
        return ["--set", f"zenoh.connect=[{self.router.endpoint}]", "--set", "zenoh.domain_id=42"]

    def subscribe(self, topic: str, latched: bool = False) -> Callable[[], list[int]]:
        arrivals = self.peer.subscribe(topic, COMMAND, latched=latched, type_hash=self.hash)
        return lambda: [deserialize_message(a.payload, message_class(COMMAND)).utime for a in list(arrivals)]

    def publisher(self, topic: str) -> Callable[[bytes], None]:
        return self.peer.publisher(topic, COMMAND, entity=7, type_hash=self.hash)

    def bridge_subscribed(self, topic: str) -> bool:
        return self.peer.subscribed(topic)  # the peer announces no subscriber of its own

    def close(self) -> None:
        self.peer.close()
        self.router.close()


def stats_of(path: Path) -> dict[str, Any]:
    try:
        return dict(json.loads(path.read_text())["routes"])
    except (OSError, ValueError, KeyError):
        return {}


def held(path: Path, route: str, channel: str) -> int:
    return int(stats_of(path).get(route, {}).get("held", {}).get(channel, {}).get("own_message", 0))


@pytest.mark.parametrize("side_class", [DdsSide, ZenohSide], ids=["dds", "zenoh"])
def test_a_channel_carried_both_ways_on_the_same_names_does_not_echo(tmp_path: Path, side_class: Any) -> None:
    url = lcm_url(81)
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    side = side_class()
    bridge = BridgeProcess(
        "-c", str(write_config(tmp_path, BOTH_WAYS.format(ros=side.transport))), "--lcm-url", url,
        "--stats-json", str(stats), "--stats-period", "0.5", *side.bridge_args(),
    )  # fmt: skip
    bus = lcm.LCM(url)
    try:
        bridge.wait_for_line(" running (")
        # LCM -> ROS. A publisher of the side's own on /A (it sends nothing) puts the topic in the
        # graph and the `back` route subscribes to it, waited for: `back` then hears every message
        # the bridge's publisher sends. (Were that publisher, made by the first message, what put
        # /A there, whether `back` heard the first would depend on which came first, its
        # subscription or that message: on a loaded machine, either.)
        side.publisher(f"/{A}")
        on_ros = side.subscribe(f"/{A}", latched=True)
        assert wait_for(lambda: side.bridge_subscribed(f"/{A}"), 60), bridge.lines[-10:]
        bus.publish(A, command(1).encode())
        assert wait_for(lambda: on_ros() == [1], 60), bridge.lines[-10:]
        assert wait_for(lambda: held(stats, "back", f"/{A}") == 1, 60), (stats_of(stats), bridge.lines[-10:])
        bus.publish(A, command(2).encode())
        assert wait_for(lambda: held(stats, "back", f"/{A}") == 2, 60), (stats_of(stats), bridge.lines[-10:])
        assert wait_for(lambda: on_ros() == [1, 2], 60), on_ros()
        recorder.sync()
        assert recorder.messages[A] == [command(1).encode(), command(2).encode()]  # the test's own: no echo

        # ROS -> LCM. The bridge sends B on LCM, hears it back, and holds it in `out`.
        heard_on_ros = side.subscribe(f"/{B}")
        publish = side.publisher(f"/{B}")
        assert wait_for(lambda: side.bridge_subscribed(f"/{B}"), 60), bridge.lines[-10:]
        publish(cdr(3))
        assert wait_for(lambda: held(stats, "out", B) == 1, 60), (stats_of(stats), bridge.lines[-10:])
        recorder.sync()
        assert recorder.messages[B] == [command(3).encode()]
        assert wait_for(lambda: heard_on_ros() == [3], 60), heard_on_ros()  # its own, no copy from the bridge
        assert wait_for(lambda: stats_of(stats).get("out", {}).get("messages_out") == 2, 30), stats_of(stats)
        assert wait_for(lambda: stats_of(stats).get("back", {}).get("messages_out") == 1, 30), stats_of(stats)
    finally:
        assert bridge.stop() == 0
        side.close()
        recorder.close()
    final = stats_of(stats)
    assert (final["out"]["messages_out"], final["back"]["messages_out"]) == (2, 1)
    assert final["back"]["held"] == {f"/{A}": {"own_message": 2}}
    assert final["out"]["held"] == {B: {"own_message": 1}}
    assert heard_on_ros() == [3] and on_ros() == [1, 2]
