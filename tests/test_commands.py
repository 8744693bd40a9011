"""The way back is shut until a channel is named, end to end: with the built-in config, an rclpy
node (DDS) and Foxglove's own ws-protocol client (Node.js) publishing `lcmt_iiwa_command` and
`lcmt_schunk_wsg_command` on /lcm_in/<channel> reach LCM only for the channels `--allow-commands`
names. A node's topic for any other channel is not even subscribed to (it costs the bridge
nothing); a Foxglove client's refused message is counted on its route and the client is told
which channel and which flag."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import pytest

from tests.conftest import lcm_url, publish_until
from tests.peers import BridgeProcess, RosProbe, wait_for
from tests.test_lcm_in import ros_from_lcm
from tests.test_router import LcmRecorder
from tests.transports.test_foxglove import foxglove_port
from tests.transports.test_foxglove_clients import WAIT, _b64, connected, statuses
from viewer_bridge.transports.ros2 import message_class

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

TYPES = {
    "IIWA_COMMAND": "drake_lcm_msgs/msg/LcmtIiwaCommand",
    "WSG_COMMAND": "drake_lcm_msgs/msg/LcmtSchunkWsgCommand",
}
ROUTES = {"ros": "lcm_in", "foxglove": "foxglove_lcm_in"}


def command(channel: str, utime: int) -> Any:
    """An lcm-gen message (pydrake's class) for the channel."""
    if channel == "IIWA_COMMAND":
        iiwa = drake_lcmtypes.lcmt_iiwa_command()
        iiwa.utime, iiwa.num_joints, iiwa.joint_position = utime, 3, [0.25, -0.5, 3.0]
        iiwa.num_torques, iiwa.joint_torque = 0, []
        return iiwa
    wsg = drake_lcmtypes.lcmt_schunk_wsg_command()
    wsg.utime, wsg.target_position_mm, wsg.force = utime, 42.5, 10.0
    return wsg


def as_json(message: Any) -> bytes:
    """The message's ROS 2 mapping as the JSON a Foxglove panel sends (these types' LCM field
    names are snake_case already, so the ROS 2 names are the same)."""
    fields = {name: getattr(message, name) for name in message.__slots__}
    return json.dumps({name: list(value) if isinstance(value, list | tuple) else value
                       for name, value in fields.items()}).encode()  # fmt: skip


def held(stats: Path, route: str, channel: str) -> int:
    try:
        counts = json.loads(stats.read_text())["routes"][route]["held"]
    except (OSError, ValueError, KeyError):
        return 0
    return int(counts.get(f"/lcm_in/{channel}", {}).get("not_allowed", 0))


@pytest.mark.parametrize(
    "allow",
    [(), ("IIWA_COMMAND|WSG_COMMAND",), ("WSG_COMMAND",)],
    ids=["default", "both-named", "wsg-only"],
)
def test_only_the_named_channels_are_commanded_from_ros_and_foxglove(
    allow: tuple[str, ...], tmp_path: Path
) -> None:
    url = lcm_url(91)
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    flags = [word for pattern in allow for word in ("--allow-commands", pattern)]
    bridge = BridgeProcess(
        "--lcm-url", url, "--stats-json", str(stats), "--stats-period", "0.3", *flags,
        "--set", "commands.max_age_ms=60000",  # freshness has tests of its own: none is late here
    )  # fmt: skip
    probe = RosProbe("commands_e2e")
    client = None
    allowed = {channel for channel in TYPES if any(re.fullmatch(pattern, channel) for pattern in allow)}
    try:
        client = connected(foxglove_port(bridge))
        (info,) = client.seen("serverInfo")
        assert ("clientPublish" in info["capabilities"]) == bool(allow), info  # offered only when it can land
        publishers = {
            channel: probe.publisher(f"/lcm_in/{channel}", typename) for channel, typename in TYPES.items()
        }
        # The bridge subscribes to the allowed channels' topics alone: another costs it nothing.
        wanted = [publisher for channel, publisher in publishers.items() if channel in allowed]
        assert probe.wait_for(lambda: all(p.get_subscription_count() >= 1 for p in wanted), 90)
        for channel, typename in TYPES.items():
            client.send(
                op="advertise", name=channel, topic=f"/lcm_in/{channel}", encoding="json", schemaName=typename
            )
        assert client.pump(WAIT, lambda: len(client.seen("advertised")) == 2), client.log()  # type: ignore[union-attr]

        sent: dict[str, list[Any]] = {channel: [] for channel in TYPES}
        for utime, channel in enumerate(TYPES, start=1):
            ros_message = command(channel, utime)
            publishers[channel].publish(ros_from_lcm(ros_message, message_class(TYPES[channel])))
            foxglove_message = command(channel, 100 + utime)
            client.send(op="publish", name=channel, data=_b64(as_json(foxglove_message)))
            sent[channel] += [ros_message, foxglove_message]

        def settled() -> bool:  # every message either on LCM or refused, from both sources
            recorder.sync()
            return all(
                len(recorder.messages.get(channel, [])) == 2 if channel in allowed
                else held(stats, ROUTES["foxglove"], channel) >= 1
                for channel in TYPES
            )  # fmt: skip

        assert wait_for(settled, WAIT), (bridge.lines[-15:], stats.read_text() if stats.exists() else "")
        # Nothing more to wait for: a refused message is counted where it would have been sent.
        for channel in TYPES:
            arrived = sorted(recorder.messages.get(channel, []))
            if channel in allowed:  # exactly lcm-gen's bytes, from each source
                assert arrived == sorted(message.encode() for message in sent[channel]), channel
            else:
                assert arrived == [], channel
                assert publishers[channel].get_subscription_count() == 0, channel  # never subscribed
                refusal = next(text for text in statuses(client) if f"/lcm_in/{channel}" in text)
                assert (
                    f"LCM channel {channel} may not be commanded" in refusal and "--allow-commands" in refusal
                )
        assert not [text for text in statuses(client) if any(f"/lcm_in/{c} " in text for c in allowed)]
    finally:
        if client is not None:
            client.close()
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def test_a_channel_seen_on_lcm_cannot_take_the_name_of_an_allowed_command(tmp_path: Path) -> None:
    """One datagram on `IIWA-COMMAND` (a sender on the bus; its ROS name token is `IIWA_COMMAND`)
    before any command: a node's command on /lcm_in/IIWA_COMMAND still reaches the allowed LCM
    `IIWA_COMMAND`, never `IIWA-COMMAND`; the allow-list alone says which channel a name commands."""
    url = lcm_url(93)
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(
        "--lcm-url", url, "--stats-json", str(stats), "--stats-period", "0.3",
        "--allow-commands", "IIWA_COMMAND", "--set", "commands.max_age_ms=60000",
    )  # fmt: skip
    probe = RosProbe("name_taker_e2e")
    try:
        bridge.wait_for_line(" running (")
        # The bridge has carried the squatter out as /lcm/IIWA_COMMAND: it has seen it.
        copies = probe.subscribe("/lcm/IIWA_COMMAND", TYPES["IIWA_COMMAND"])
        squatter = command("IIWA_COMMAND", 7).encode()
        publish_until(url, squatter, lambda: len(copies) >= 1, channel="IIWA-COMMAND")
        publisher = probe.publisher("/lcm_in/IIWA_COMMAND", TYPES["IIWA_COMMAND"])
        assert probe.wait_for(lambda: publisher.get_subscription_count() >= 1, 90)
        real = command("IIWA_COMMAND", 8)
        publisher.publish(ros_from_lcm(real, message_class(TYPES["IIWA_COMMAND"])))
        assert wait_for(lambda: "IIWA_COMMAND" in recorder.messages, WAIT), (
            bridge.lines[-15:],
            stats.read_text() if stats.exists() else "",
        )
        recorder.sync()
        assert recorder.messages["IIWA_COMMAND"] == [real.encode()]
        assert set(recorder.messages["IIWA-COMMAND"]) == {squatter}  # only the squatter's own
        assert not [line for line in bridge.lines if "may not be commanded" in line], bridge.lines
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def test_two_allowed_channels_that_would_take_one_name_are_said_at_start() -> None:
    bridge = BridgeProcess(
        "--lcm-url", lcm_url(94), "--allow-commands", "IIWA_COMMAND", "--allow-commands", "IIWA-COMMAND|WSG_COMMAND"
    )  # fmt: skip
    try:
        line = bridge.wait_for_line("would both be commanded as /lcm_in/IIWA_COMMAND")
        assert "it commands IIWA_COMMAND; IIWA-COMMAND cannot be commanded" in line, line
    finally:
        assert bridge.stop() == 0
