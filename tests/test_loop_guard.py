"""The loop guard (viewer_bridge/router/echoes.py) with real transports: a bridge that carries
channels both ways on the same names (LCM LOOP_* -> ROS 2 /LOOP_* by `lcm_to_ros`, and ROS 2
/LOOP_* -> LCM LOOP_* by `ros_to_lcm`) passes one message in as exactly one out, each way, and
counts its own message coming back (held: `own_message`) instead of sending it round again.
The channels name their type (`lcmt_iiwa_command` shares its fingerprint with
`lcmt_allegro_command`: the channel's name picks)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import lcm
import pytest

from tests.conftest import lcm_url
from tests.peers import BridgeProcess, RosProbe, wait_for, write_config
from tests.test_lcm_in import ros_from_lcm
from tests.test_router import LcmRecorder
from viewer_bridge.transports.ros2 import message_class

pytestmark = pytest.mark.slow

BOTH_WAYS = """\
routes:
  - name: out
    source: {transport: lcm, name: "(LOOP_.*)"}
    translator: lcm_to_ros
    destination: {transport: ros, name: "/{1}"}
    qos: {depth: 100, durability: transient_local}
    rate: {policy: all}
  - name: back
    source: {transport: ros, name: "/(LOOP_.*)"}
    translator: ros_to_lcm
    destination: {transport: lcm, name: "{1}"}
    qos: {depth: 100}
    rate: {policy: all}
"""
COMMAND = "drake_lcm_msgs/msg/LcmtIiwaCommand"


def command(utime: int) -> Any:
    message = drake_lcmtypes.lcmt_iiwa_command()
    message.utime, message.num_joints, message.joint_position = utime, 2, [0.5, -0.25]
    message.num_torques, message.joint_torque = 0, []
    return message


def stats_of(path: Path) -> dict[str, Any]:
    try:
        return dict(json.loads(path.read_text()))
    except (OSError, ValueError):
        return {}


def held(path: Path, route: str, channel: str) -> int:
    return int(stats_of(path).get(route, {}).get("held", {}).get(channel, {}).get("own_message", 0))


def test_a_channel_carried_both_ways_on_the_same_names_does_not_echo(tmp_path: Path) -> None:
    url = lcm_url(81)
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(
        "-c", str(write_config(tmp_path, BOTH_WAYS)), "--lcm-url", url,
        "--stats-json", str(stats), "--stats-period", "0.5",
    )  # fmt: skip
    probe = RosProbe("loop_probe")
    bus = lcm.LCM(url)
    try:
        bridge.wait_for_line(" running (")
        # LCM -> ROS. The first message makes the bridge's publisher on /LOOP_IIWA_COMMAND_A; the `back` route
        # then finds the topic in the graph and subscribes: from then on it hears its own publisher.
        on_ros = probe.subscribe("/LOOP_IIWA_COMMAND_A", COMMAND, latched=True)  # gets the first even if matched after it
        bus.publish("LOOP_IIWA_COMMAND_A", command(1).encode())
        assert probe.wait_for(lambda: len(on_ros) == 1, 60), bridge.lines[-10:]
        # Two subscribers: the probe's and the bridge's own.
        assert probe.wait_for(lambda: probe.node.count_subscribers("/LOOP_IIWA_COMMAND_A") >= 2, 60)
        bus.publish("LOOP_IIWA_COMMAND_A", command(2).encode())
        assert wait_for(lambda: held(stats, "back", "/LOOP_IIWA_COMMAND_A") == 1, 60), (stats_of(stats), bridge.lines[-10:])
        assert probe.wait_for(lambda: len(on_ros) == 2, 60)
        recorder.sync()
        assert [message.utime for message in on_ros] == [1, 2]
        # Only the test's own two: no echo.
        assert recorder.messages["LOOP_IIWA_COMMAND_A"] == [command(1).encode(), command(2).encode()]

        # ROS -> LCM. The bridge sends LOOP_IIWA_COMMAND_B on LCM, hears it back, and holds it in `out`.
        publisher = probe.publisher("/LOOP_IIWA_COMMAND_B", COMMAND)
        heard_on_ros = probe.subscribe("/LOOP_IIWA_COMMAND_B", COMMAND)
        assert probe.wait_for(lambda: publisher.get_subscription_count() >= 2, 60)  # the probe's and the bridge's
        publisher.publish(ros_from_lcm(command(3), message_class(COMMAND)))
        assert wait_for(lambda: held(stats, "out", "LOOP_IIWA_COMMAND_B") == 1, 60), (stats_of(stats), bridge.lines[-10:])
        recorder.sync()
        assert recorder.messages["LOOP_IIWA_COMMAND_B"] == [command(3).encode()]
        assert probe.wait_for(lambda: len(heard_on_ros) >= 1, 60)
        assert [message.utime for message in heard_on_ros] == [3]  # its own, and no copy from the bridge
        assert wait_for(lambda: stats_of(stats).get("out", {}).get("messages_out") == 2, 30), stats_of(stats)
        assert wait_for(lambda: stats_of(stats).get("back", {}).get("messages_out") == 1, 30), stats_of(stats)
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()
    final = stats_of(stats)
    assert (final["out"]["messages_out"], final["back"]["messages_out"]) == (2, 1)
    assert final["back"]["held"] == {"/LOOP_IIWA_COMMAND_A": {"own_message": 1}}
    assert final["out"]["held"] == {"LOOP_IIWA_COMMAND_B": {"own_message": 1}}
