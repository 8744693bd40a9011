"""One clock for the whole bridge (the config's `time:`): `/tf`, `/clock`, Foxglove's time and an
MCAP file's log times, end to end with real peers: the bridge as a process, an rclpy node, a
Foxglove client written from the WebSocket protocol (JSON control messages; binary server
opcodes 1 `message data`: u32 subscription id, u64 LE log time ns, payload; 2 `time`: u64 LE ns),
and the MCAP files `viewer-bridge convert` writes."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from websockets.sync.client import connect

from tests.conftest import lcm_url
from tests.peers import BridgeProcess, RosProbe, write_config
from tests.transports.test_foxglove import SUBPROTOCOLS, foxglove_port
from viewer_bridge.config.bridge import DEFAULT_CONFIG, load_config
from viewer_bridge.examples.scenes import draw_of, small_scene
from viewer_bridge.shared import Clock, Shared
from viewer_bridge.translators.load_cache import LoadCache
from viewer_bridge.transports.lcm import LcmBus

SIM_SECONDS = 4242.125  # Drake's sim time in the draws: nowhere near the wall clock
SIM_NS = 4_242_125_000_000
TRANSFORMS = "/drake/transforms"  # builtin:default's Foxglove transforms of the unsuffixed draws


# --- the clock and the config ----------------------------------------------------------------------


def test_the_clock_follows_the_newest_draw_received_and_goes_back_only_for_a_restart() -> None:
    clock, heard = Clock("sim"), []
    clock.listen(heard.append)
    clock.tick(2_000_000, received_us=100)
    clock.tick(2_000_000, received_us=101)  # the same time again (another role's draw): said once
    clock.tick(1_000_000, received_us=99)  # an older draw decoded late (a lagging route): ignored
    assert (clock.now_ns, heard) == (2_000_000, [2_000_000])
    clock.tick(5_000, received_us=200)  # a newer draw with an earlier time: a restarted simulation
    assert (clock.now_ns, heard) == (5_000, [2_000_000, 5_000])
    assert clock.log_time_ns(received_us=7) == 5_000
    receive = Clock()
    receive.tick(2_000_000, received_us=100)
    assert receive.now_ns == 0 and receive.log_time_ns(received_us=7) == 7_000


@pytest.mark.parametrize("time_source", ["receive", "sim"])
def test_every_stamping_translator_follows_the_clock_unless_its_route_says(time_source: str) -> None:
    from geometry_msgs.msg import PoseArray
    from rclpy.serialization import deserialize_message
    from tf2_msgs.msg import TFMessage

    from viewer_bridge.translators.registry import TRANSLATORS
    from viewer_bridge.transports.base import Received

    shared = Shared(time=time_source, given=[LoadCache()])  # type: ignore[arg-type]
    received = Received("DRAKE_VIEWER_DRAW", draw_of(small_scene(), SIM_SECONDS), 1_700_000_000_250_000)
    expected = SIM_NS if time_source == "sim" else 1_700_000_000_250_000_000

    def stamps(translator: str, options: dict[str, Any]) -> set[int]:
        (_, data), *_ = TRANSLATORS.get(translator)(options, shared=shared).translate(received)
        if translator == "drake_to_tf":
            return {_ns(t.header.stamp) for t in deserialize_message(data, TFMessage).transforms}
        if translator == "drake_to_pose_array":
            return {_ns(deserialize_message(data, PoseArray).header.stamp)}
        return set(_transform_stamps([(0, data)]))

    for translator in ("drake_to_tf", "drake_to_pose_array", "drake_to_frame_transforms"):
        assert stamps(translator, {}) == {expected}, translator
        assert stamps(translator, {"stamp": "receive"}) == {1_700_000_000_250_000_000}, translator
        assert stamps(translator, {"stamp": "sim"}) == {SIM_NS}, translator
    # The router's one decoding of the draw moved the clock (sim only).
    assert shared.clock.now_ns == (SIM_NS if time_source == "sim" else 0)


def test_time_sim_adds_a_clock_route_per_ros_graph_and_receive_none() -> None:
    default = load_config("builtin:default")
    assert default.time == "receive" and not [r for r in default.routes if r.translator == "drake_to_clock"]
    sim = default.with_keys(time="sim")
    (clock,) = [route for route in sim.routes if route.translator == "drake_to_clock"]
    assert (clock.name, clock.destination.transport, clock.destination.name) == ("clock_ros", "ros", "/clock")
    assert clock.source.transport == "lcm" and clock.source.name.startswith("DRAKE_VIEWER_DRAW")
    # No ROS graph, no /clock (Foxglove gets the time capability instead).
    foxglove = load_config("builtin:foxglove").with_keys(time="sim")
    assert not [route for route in foxglove.routes if route.translator == "drake_to_clock"]


def test_set_time_on_the_command_line_is_checked_as_the_config_key(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "run", "--set", "time=wall", "--duration", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode != 0
    assert "--set time=wall: time: Input should be 'receive' or 'sim'" in result.stderr


# --- end to end ------------------------------------------------------------------------------------


class TimeClient:
    """A Foxglove client from the protocol: the server's capabilities, its time messages (opcode
    2) and, for the topics it subscribes to, each message's log time and payload (opcode 1)."""

    def __init__(self, port: int) -> None:
        self._connection = connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS,  # type: ignore[arg-type]
                                   ping_interval=None, max_queue=None)  # fmt: skip
        self.ws = self._connection.__enter__()
        self.capabilities: list[str] | None = None
        self.channels: dict[str, int] = {}  # topic -> channel id
        self.times: list[int] = []
        self.messages: dict[str, list[tuple[int, bytes]]] = {}  # topic -> (log time, payload)
        self._topics: dict[int, str] = {}

    def pump(self, seconds: float, until: Callable[[], bool]) -> bool:
        deadline = time.monotonic() + seconds
        while not until() and time.monotonic() < deadline:
            try:
                frame = self.ws.recv(timeout=max(0.01, min(0.5, deadline - time.monotonic())))
            except TimeoutError:
                continue
            if isinstance(frame, str):
                message = json.loads(frame)
                if message["op"] == "serverInfo":
                    self.capabilities = message["capabilities"]
                elif message["op"] == "advertise":
                    self.channels.update({channel["topic"]: channel["id"] for channel in message["channels"]})
            elif frame[0] == 0x02:  # time: u64 LE ns
                self.times.append(struct.unpack_from("<Q", frame, 1)[0])
            elif frame[0] == 0x01:  # message data: u32 subscription, u64 LE log time, payload
                subscription, log_time = struct.unpack_from("<IQ", frame, 1)
                self.messages.setdefault(self._topics[subscription], []).append((log_time, bytes(frame[13:])))
        return until()

    def subscribe(self, topic: str) -> None:
        assert self.pump(60, lambda: topic in self.channels), self.channels
        subscription = len(self._topics) + 1
        self._topics[subscription] = topic
        wanted = [{"id": subscription, "channelId": self.channels[topic]}]
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": wanted}))

    def close(self) -> None:
        self._connection.__exit__(None, None, None)


@pytest.fixture
def probe() -> Iterator[RosProbe]:
    node = RosProbe("clock_probe")
    yield node
    node.close()


class Draws:
    """Drake's draws of one sim time on the bus, every 50 ms, until closed (UDP may drop one; a
    route may start late)."""

    def __init__(self, url: str) -> None:
        self._bus = LcmBus(url)
        self._draw = draw_of(small_scene(), SIM_SECONDS)
        self._stop = threading.Event()
        self.first_us = time.time_ns() // 1000
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(0.05):
            self._bus.publish("DRAKE_VIEWER_DRAW", self._draw)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self._bus.close()


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _transform_stamps(payloads: list[tuple[int, bytes]]) -> list[int]:
    stamps = []
    for _, payload in payloads:
        message = FrameTransforms()
        message.ParseFromString(payload)
        stamp = message.transforms[0].timestamp
        stamps.append(int(stamp.seconds) * 1_000_000_000 + int(stamp.nanos))
    return stamps


@pytest.mark.slow
@pytest.mark.e2e
def test_with_time_sim_clock_tf_and_foxglove_time_are_the_draws_sim_time(probe: RosProbe) -> None:
    url = lcm_url(51)
    clock = probe.subscribe("/clock", "rosgraph_msgs/msg/Clock")
    tf = probe.subscribe("/tf", "tf2_msgs/msg/TFMessage")
    bridge = BridgeProcess(
        "-c", "builtin:default", "--set", "time=sim", "--lcm-url", url, "--stats-period", "1"
    )
    client = draws = None
    try:
        port = foxglove_port(bridge)
        draws = Draws(url)
        client = TimeClient(port)
        client.subscribe(TRANSFORMS)
        assert client.pump(60, lambda: bool(client.times) and bool(client.messages.get(TRANSFORMS))), (
            client.capabilities, client.times[-3:], client.channels)  # fmt: skip
        assert probe.wait_for(lambda: bool(clock) and bool(tf)), bridge.lines[-10:]
    finally:
        if draws is not None:
            draws.close()
        if client is not None:
            client.close()
        assert bridge.stop() == 0
    assert client.capabilities is not None and "time" in client.capabilities
    assert set(client.times) == {SIM_NS}
    assert {log_time for log_time, _ in client.messages[TRANSFORMS]} == {SIM_NS}  # log times
    assert set(_transform_stamps(client.messages[TRANSFORMS])) == {SIM_NS}  # and stamps
    assert {_ns(message.clock) for message in clock} == {SIM_NS}
    assert {_ns(t.header.stamp) for message in tf for t in message.transforms} == {SIM_NS}


@pytest.mark.slow
@pytest.mark.e2e
def test_by_default_stamps_are_receive_times_and_there_is_no_clock(probe: RosProbe) -> None:
    url = lcm_url(52)
    clock = probe.subscribe("/clock", "rosgraph_msgs/msg/Clock")
    tf = probe.subscribe("/tf", "tf2_msgs/msg/TFMessage")
    bridge = BridgeProcess("-c", "builtin:default", "--lcm-url", url, "--stats-period", "1")
    client = draws = None
    try:
        port = foxglove_port(bridge)
        draws = Draws(url)
        client = TimeClient(port)
        client.subscribe(TRANSFORMS)
        assert client.pump(60, lambda: len(client.messages.get(TRANSFORMS, [])) >= 3), client.channels
        assert probe.wait_for(lambda: len(tf) >= 3), bridge.lines[-10:]
        publishers = probe.node.count_publishers("/clock")
        ended_ns = time.time_ns()
    finally:
        if draws is not None:
            draws.close()
        if client is not None:
            client.close()
        assert bridge.stop() == 0
    assert client.capabilities is not None and "time" not in client.capabilities and not client.times
    assert publishers == 0 and not clock
    started_ns = draws.first_us * 1000
    stamps = {_ns(t.header.stamp) for message in tf for t in message.transforms}
    assert all(started_ns <= stamp <= ended_ns for stamp in stamps), (started_ns, stamps, ended_ns)
    # Foxglove's transforms: receive times as /tf's (no longer sim time), logged at about then too.
    foxglove = _transform_stamps(client.messages[TRANSFORMS])
    assert all(started_ns <= stamp <= ended_ns for stamp in foxglove), (started_ns, foxglove, ended_ns)
    assert all(started_ns <= log_time <= ended_ns for log_time, _ in client.messages[TRANSFORMS])


@pytest.mark.slow
@pytest.mark.parametrize("schema", ["ros2", "foxglove"])
def test_convert_with_time_sim_logs_and_stamps_at_the_draws_sim_time(
    drake_log: Path, tmp_path: Path, schema: str
) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from viewer_bridge.transports.lcm import read_log

    config = yaml.safe_load(DEFAULT_CONFIG)
    config["time"] = "sim"
    path = write_config(tmp_path, yaml.safe_dump(config))
    out = tmp_path / f"sim_{schema}.mcap"
    command = ["convert", str(drake_log), str(out), "-c", str(path), "--schema", schema]
    result = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", *command], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    draws = [event.data for event in read_log(drake_log, "DRAKE_VIEWER_DRAW_ILLUSTRATION")]
    from drake import lcmt_viewer_draw

    sim_ns = [lcmt_viewer_draw.decode(data).timestamp * 1_000_000 for data in draws]
    topics: dict[str, list[tuple[int, Any]]] = {}
    with out.open("rb") as file:
        reader = make_reader(file, decoder_factories=[DecoderFactory()] if schema == "ros2" else [])
        if schema == "ros2":
            for _, channel, message, decoded in reader.iter_decoded_messages():
                topics.setdefault(channel.topic, []).append((message.log_time, decoded))
        else:
            for _, channel, message in reader.iter_messages():
                topics.setdefault(channel.topic, []).append((message.log_time, message.data))
    if schema == "ros2":
        poses = topics["/drake/illustration/poses"]
        assert [log_time for log_time, _ in poses] == sim_ns == [_ns(p.header.stamp) for _, p in poses]
        # /clock: each draw's sim time, of every role (Drake draws them at the same times).
        clock = topics["/clock"]
        assert {_ns(c.clock) for _, c in clock} == set(sim_ns)
        assert all(log_time == _ns(c.clock) for log_time, c in clock)
    else:
        transforms = topics["/drake/illustration/transforms"]
        assert [log_time for log_time, _ in transforms] == sim_ns == _transform_stamps(transforms)
    # Everything else is logged at the newest draw's sim time, never the wall clock.
    every = [log_time for messages in topics.values() for log_time, _ in messages]
    assert max(every) <= max(sim_ns)
