"""The router end to end, with real peers: pydrake over LCM, the bridge as a process, rclpy."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest

from tests.conftest import DRAKE_SCENE_SCRIPT, SYNC_CHANNEL, lcm_url, publish_until
from tests.formats import oracle
from tests.peers import BridgeProcess, RosProbe, write_config
from viewer_bridge.config.bridge import DEFAULT_CONFIG, destination_name, load_config
from viewer_bridge.errors import ConfigError
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.model.scene import LinkPoses
from viewer_bridge.transports.base import Received
from viewer_bridge.transports.lcm import LcmBus

pytestmark = [pytest.mark.slow, pytest.mark.e2e]


@pytest.fixture
def probe() -> Any:
    node = RosProbe()
    yield node
    node.close()


class LcmRecorder:
    """Every message on an LCM URL, recorded by channel (a bus of the test's own)."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.bus = LcmBus(url)
        self.messages: dict[str, list[bytes]] = {}
        self.bus.subscribe(
            ".*", lambda channel, data, _: self.messages.setdefault(channel, []).append(bytes(data))
        )
        self.bus.start()

    def sync(self) -> None:
        """Return once every message published on the URL before this call has been recorded."""
        mark = uuid.uuid4().bytes
        publish_until(self.url, mark, lambda: mark in self.messages.get(SYNC_CHANNEL, []))

    def close(self) -> None:
        self.bus.close()


def start_drake(url: str, folder: Path, seconds: float) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, str(DRAKE_SCENE_SCRIPT), url, str(folder), str(seconds)])


# --- 1. Drake -> bridge -> rclpy, values checked ---------------------------------------------------


def test_drake_simulation_reaches_ros_through_the_bridge(probe: RosProbe, tmp_path: Path) -> None:
    url = lcm_url(1)
    poses = probe.subscribe("/drake/illustration/poses", "geometry_msgs/msg/PoseArray")
    markers = probe.subscribe(
        "/drake/illustration/markers", "visualization_msgs/msg/MarkerArray", 10, latched=True
    )
    primitives = probe.subscribe(
        "/drake/illustration/shapes/primitives", "shape_msgs/msg/SolidPrimitive", 1000, latched=True
    )
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(  # time: sim: the PoseArray's stamp tells Drake's last draw
        "--lcm-url",
        url,
        "--stats-json",
        str(tmp_path / "stats.json"),
        "--stats-period",
        "1",
        "--set",
        "time=sim",
    )
    try:
        bridge.wait_for_line(" running (")
        drake = start_drake(url, tmp_path, 3.0)
        assert drake.wait(timeout=120) == 0
        recorder.sync()  # holds Drake's last draw
        draws = recorder.messages["DRAKE_VIEWER_DRAW_ILLUSTRATION"]
        last_draw = drake_lcmtypes.lcmt_viewer_draw.decode(draws[-1])
        stamp = last_draw.timestamp
        assert probe.wait_for(lambda: any(_stamp_ms(p.header.stamp) == stamp for p in poses))
        load = drake_lcmtypes.lcmt_viewer_load_robot.decode(
            recorder.messages["DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION"][0]
        )
        box_link = next(link for link in load.link if link.name.endswith("robot1::body0"))
        row = list(last_draw.link_name).index(box_link.name)
        box_position, box_xyzw = oracle.world_pose(
            last_draw.position[row], last_draw.quaternion[row], box_link.geom[0]
        )

        def box(array: Any) -> Any:
            (marker,) = [m for m in array.markers if m.ns == box_link.name.replace("::", "/")]
            return marker

        def at_last_draw(marker: Any) -> bool:
            return oracle.close(
                [marker.pose.position.x, marker.pose.position.y, marker.pose.position.z], box_position
            )

        def last_drawn() -> Any:  # the load's array (DELETEALL first) has its own, latched writer
            drawn = [array for array in markers if array.markers[0].action != 3]
            return drawn[-1] if drawn else None

        # The last draw's MarkerArray (its markers carry no stamp) follows the last PoseArray.
        assert probe.wait_for(lambda: last_drawn() is not None and at_last_draw(box(last_drawn())))
    finally:
        assert bridge.stop() == 0
        recorder.close()
    # PoseArray: every link of the draw, in order, x-y-z-w.
    pose_array = next(p for p in poses if _stamp_ms(p.header.stamp) == stamp)
    assert len(pose_array.poses) == last_draw.num_links
    for pose, position, (w, x, y, z) in zip(
        pose_array.poses, last_draw.position, last_draw.quaternion, strict=True
    ):
        assert [pose.position.x, pose.position.y, pose.position.z] == list(position)
        assert [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w] == [
            x,
            y,
            z,
            w,
        ]
    # MarkerArray: every array is the full model (the load's starts with DELETEALL, but DDS may have
    # matched this subscriber after it left the latched history); the last one at the last draw.
    assert all(len([m for m in array.markers if m.action == 0]) >= 16 for array in markers)
    last_box = box(last_drawn())
    assert at_last_draw(last_box)
    orientation = last_box.pose.orientation
    assert oracle.same_rotation([orientation.x, orientation.y, orientation.z, orientation.w], box_xyzw)
    assert oracle.close([last_box.scale.x, last_box.scale.y, last_box.scale.z], [0.1, 0.2, 0.3])
    # shape_msgs: SolidPrimitive per primitive geometry, cylinder HEIGHT first.
    dimensions = {(p.type, tuple(np.float32(p.dimensions).tolist())) for p in primitives}
    assert (1, tuple(np.float32([0.1, 0.2, 0.3]).tolist())) in dimensions
    assert (3, tuple(np.float32([0.3, 0.04]).tolist())) in dimensions
    stats = json.loads((tmp_path / "stats.json").read_text())["routes"]
    assert stats["poses"]["messages_out"] >= 1 and stats["markers"]["errors"] == {}


def _stamp_ms(stamp: Any) -> int:
    return int(stamp.sec) * 1000 + int(stamp.nanosec) // 1_000_000


def _settled(route: dict[str, Any] | None, received: int) -> bool:
    """A lazy route's stats while nobody listens, once `received` messages are in and each one
    is published, skipped or dropped (a non-lazy route here publishes one message per draw)."""
    if route is None or route["messages_in"] < received or route["queued"]:
        return False
    done = route["messages_out"] + route["idle_skipped"] + route["dropped"] + sum(route["errors"].values())
    return bool(done >= route["messages_in"])


def _active(route: dict[str, Any] | None, received: int) -> bool:
    """A route's stats once `received` messages are in and it translates them for a subscriber."""
    return route is not None and route["messages_in"] >= received and route["state"] == "active"


# --- 2. ROS 2 -> LCM ---------------------------------------------------------------------------------

ROS_TO_LCM = """\
routes:
  - name: from_ros
    source: {transport: ros, name: /drake_in/poses}
    translator: ros_pose_array_to_drake_draw
    destination: {transport: lcm, name: DRAKE_VIEWER_DRAW_FROM_ROS}
    rate: {policy: all}
    options: {link_names: ["plant::a", "plant::b"], robot_nums: [2, 3]}
"""


def test_ros_pose_array_arrives_as_a_drake_draw(probe: RosProbe, tmp_path: Path) -> None:
    from geometry_msgs.msg import Pose, PoseArray

    url = lcm_url(2)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("-c", str(write_config(tmp_path, ROS_TO_LCM)), "--lcm-url", url)
    publisher = probe.publisher("/drake_in/poses", "geometry_msgs/msg/PoseArray")
    message = PoseArray()
    message.header.stamp.sec, message.header.stamp.nanosec = 12, 345_000_000
    for x in (1.0, 2.0):
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = x, 0.5, -0.25
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = 0.0, 0.0, 0.6, 0.8
        message.poses.append(pose)
    try:
        bridge.wait_for_line(" running (")
        received = lambda: recorder.messages.get("DRAKE_VIEWER_DRAW_FROM_ROS")  # noqa: E731
        deadline = time.monotonic() + 60
        while not received() and time.monotonic() < deadline:  # until discovery has matched the two
            publisher.publish(message)
            time.sleep(0.2)
    finally:
        assert bridge.stop() == 0
        recorder.close()
    draws = received()
    assert draws, "no lcmt_viewer_draw arrived"
    draw = drake_lcmtypes.lcmt_viewer_draw.decode(draws[0])  # Drake's own class reads it
    assert draw.timestamp == 12_345 and list(draw.link_name) == ["plant::a", "plant::b"]
    assert list(draw.robot_num) == [2, 3]
    assert [list(p) for p in draw.position] == [[1.0, 0.5, -0.25], [2.0, 0.5, -0.25]]
    assert oracle.close(draw.quaternion, [[0.8, 0.0, 0.0, 0.6]] * 2)  # w first in Drake's message


# --- 3. Late subscribers, and a bridge started after the simulation -----------------------------------


def test_late_subscriber_and_late_bridge_get_the_model(probe: RosProbe, tmp_path: Path) -> None:
    url = lcm_url(3)
    cache = tmp_path / "loads"
    config = write_config(tmp_path, DEFAULT_CONFIG + f"load_cache: {cache}\n")
    first = BridgeProcess("-c", str(config), "--lcm-url", url)
    try:
        first.wait_for_line(" running (")
        assert start_drake(url, tmp_path, 1.5).wait(timeout=120) == 0
        kept = cache / "DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION.lcm"  # the bridge keeps each load it reads
        deadline = time.monotonic() + 60
        while not kept.is_file() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert kept.is_file(), "the bridge never read the model"
        # A subscriber that starts now, after the model was published, still gets it.
        late = probe.subscribe(
            "/drake/illustration/markers", "visualization_msgs/msg/MarkerArray", 1, latched=True
        )
        assert probe.wait_for(lambda: len(late) >= 1)
        assert len(late[-1].markers) >= 16
    finally:
        assert first.stop() == 0
    assert (cache / "DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION.lcm").is_file()
    # The simulation starts (and sends its one load) before this bridge does.
    drake = start_drake(url, tmp_path, 12.0)
    recorder = LcmRecorder(url)
    try:
        deadline = time.monotonic() + 60
        while "DRAKE_VIEWER_DRAW_PROXIMITY" not in recorder.messages and time.monotonic() < deadline:
            time.sleep(0.1)
        assert "DRAKE_VIEWER_LOAD_ROBOT_PROXIMITY" in recorder.messages  # sent: Drake will not send it again
        second = BridgeProcess("-c", str(config), "--lcm-url", url)
        try:
            second.wait_for_line(" running (")
            fresh = probe.subscribe(
                "/drake/proximity/markers", "visualization_msgs/msg/MarkerArray", 1, latched=True
            )
            assert probe.wait_for(lambda: any(len(m.markers) >= 16 for m in fresh), timeout=30)
        finally:
            assert second.stop() == 0
        assert (
            len(recorder.messages["DRAKE_VIEWER_LOAD_ROBOT_PROXIMITY"]) == 1
        )  # the model came from the cache
    finally:
        drake.kill()
        drake.wait(timeout=60)
        recorder.close()


# --- 4. Bad input: a malformed message mid-stream, a broken config -------------------------------------

EVERY_DRAW = """\
routes:
  - name: poses
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: drake_to_pose_array
    destination: {transport: ros, name: /stream/poses}
    qos: {depth: 1000}
    rate: {policy: all}
    options: {stamp: sim}  # each PoseArray stamped with its draw's time, which tells them apart
"""


def test_a_malformed_message_is_counted_and_nothing_valid_is_lost(probe: RosProbe, tmp_path: Path) -> None:
    url = lcm_url(4)
    received = probe.subscribe("/stream/poses", "geometry_msgs/msg/PoseArray", 1000)
    stats = tmp_path / "stats.json"
    bridge = BridgeProcess(
        "-c", str(write_config(tmp_path, EVERY_DRAW)), "--lcm-url", url, "--stats-json", str(stats)
    )
    bus = LcmBus(url)
    encoder = DrawEncoder()
    names = ("plant::a", "plant::b")

    def draw(timestamp_ms: int) -> bytes:
        positions = np.array([[timestamp_ms, 0.0, 0.0], [0.0, timestamp_ms, 0.0]])
        quaternions = np.array([[1.0, 0.0, 0.0, 0.0]] * 2)
        return encoder.encode(
            LinkPoses(timestamp_ms, names, np.array([1, 1], np.int32), positions, quaternions)
        )

    try:
        bridge.wait_for_line(" running (")
        deadline = time.monotonic() + 60
        while not received and time.monotonic() < deadline:  # until discovery has matched the two
            bus.publish("DRAKE_VIEWER_DRAW", draw(0))
            time.sleep(0.2)
        # Matched, and reliable: every draw from here on arrives (the late draws of 0 are left out below).
        for timestamp in range(1, 101):
            bus.publish("DRAKE_VIEWER_DRAW", draw(timestamp))
            if timestamp == 50:
                bus.publish("DRAKE_VIEWER_DRAW", draw(999)[:-7])  # truncated mid-quaternion
                bus.publish("DRAKE_VIEWER_DRAW", b"\x41\x42\x43")  # not even a header
            time.sleep(0.002)
        assert probe.wait_for(lambda: len(received) >= 100)
    finally:
        assert bridge.stop() == 0
        bus.close()
    assert [_stamp_ms(m.header.stamp) for m in received if _stamp_ms(m.header.stamp)] == list(range(1, 101))
    route = json.loads(stats.read_text())["routes"]["poses"]
    assert route["errors"] == {"DecodeError": 2}
    assert route["dropped"] == 0
    warnings = [line for line in bridge.lines if "DecodeError" in line]
    assert any("drake.lcmt_viewer_draw" in line and "truncated" in line for line in warnings), bridge.lines


BROKEN_CONFIGS = [
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: teleport\n"
     "    destination: {transport: ros, name: /x}\n", 4, "routes.0.translator", "unknown translator 'teleport'"),
    # A misspelt translator: the closest known name is suggested.
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_pose_arrays\n"
     "    destination: {transport: ros, name: /x}\n", 4, "routes.0.translator",
     "unknown translator 'drake_to_pose_arrays' (did you mean 'drake_to_pose_array'? known: drake_to_marker_array,"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: 'X('}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: /x}\n", 3, "routes.0.source", "not a regular expression"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: /x}\n    qos: {depth: many}\n", 6, "routes.0.qos.depth",
     "valid integer"),
    ("routes:\n  - name: a\n    source: {transport: zmq, name: X}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: /x}\n", 3, "routes.0.source.transport",
     "'zmq' is not a transport (transports: lcm, ros, ign"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: '/x/{2}'}\n", 2, "routes.0", "does not fit a source with 0 groups"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_ign_pose_v\n"
     "    destination: {transport: ign, name: /x}\n    options: {package: gazebo}\n", 6,
     "routes.0.options.package", "Input should be 'ignition' or 'gz'"),
    ("routes:\n  - name: a\n    source: {transport: ign, name: '/robot.+/pose_v'}\n"
     "    translator: ign_pose_v_to_drake_draw\n    destination: {transport: lcm, name: X}\n", 3,
     "routes.0.source.name", "an ign source is one topic name"),
    # Options are the translator's model: a misspelt key and a wrong type are refused at load.
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: /x}\n    options:\n      frmae_id: map\n", 7,
     "routes.0.options.frmae_id", "unknown key 'frmae_id' (did you mean 'frame_id'?); known keys: stamp, frame_id"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_ign_model\n"
     "    destination: {transport: ign, name: /x}\n    options: {republish_s: soon}\n", 6,
     "routes.0.options.republish_s", "valid number"),
    # The translator's declared types must travel over the route's transports.
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: lcm, name: Y}\n", 5, "routes.0.destination.transport",
     "translator drake_to_pose_array writes geometry_msgs/msg/PoseArray (cdr), which the lcm transport does not carry"),
    ("routes:\n  - name: a\n    source: {transport: ros, name: /x}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: /y}\n", 3, "routes.0.source.transport",
     "translator drake_to_pose_array reads drake.lcmt_viewer_draw (lcm), which the ros transport does not carry"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_ign_pose_v\n"
     "    destination: {transport: ros, name: /y}\n", 5, "routes.0.destination.transport",
     "writes Pose_V (protobuf), which the ros transport does not carry"),
    # Transport sections are checked by the transport's own settings model.
    ("lcm: {uri: 'udpm://x'}\nroutes: []\n", 1, "lcm.uri", "unknown key 'uri' (did you mean 'url'?); known keys: url"),
    # A misspelt key is named as unknown, not only as the key it leaves missing.
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translater: drake_to_pose_array\n"
     "    destination: {transport: ros, name: /x}\n", 4, "routes.0.translater",
     "unknown key 'translater' (did you mean 'translator'?); known keys: name, source, translator, destination"),
    # ROS names by ROS 2's rules (rcl's topic name validation), refused at load, not at each publish.
    ("routes:\n  - name: a\n    source: {transport: lcm, name: 'X(_.*)?'}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: '/sim2/bad topic!'}\n", 5, "routes.0.destination.name",
     "'/sim2/bad topic!' is not a valid ROS 2 topic name: it has characters a ROS name cannot hold: ' !'"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: 'X(_.*)?'}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: 'drake/{1:lower}/2d'}\n", 5, "routes.0.destination.name",
     "'drake/x/2d' is not a valid ROS 2 topic name: a part of it starts with a digit: '2d'"),
    ("routes:\n  - name: a\n    source: {transport: ros, name: /in//cloud}\n    translator: ros_point_cloud_to_drake\n"
     "    destination: {transport: lcm, name: X}\n", 3, "routes.0.source.name", "it has // (an empty part)"),
    ("ros: {namespace: /sim2/2d}\nroutes: []\n", 1, "ros.namespace",
     "'/sim2/2d' is not a valid ROS 2 namespace: a part of it starts with a digit: '2d'"),
    ("ros:\n  node: viewer-bridge\nroutes: []\n", 2, "ros.node",
     "'viewer-bridge' is not a valid ROS 2 node name: it has characters a ROS name cannot hold: '-'"),
    ("routes: []\nzmq: {port: 1}\n", 2, "zmq",
     "'zmq' is not a config key (load_cache, lcm_types, drake_lcm_types, commands, ros_topics, workers, time, routes) "
     "nor a transport"),
    ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: drake_to_pose_array\n"
     "    destination: {transport: ros, name: /x}\n  - name: a\n    source: {transport: lcm, name: X}\n"
     "    translator: drake_to_clock\n    destination: {transport: ros, name: /c}\n", 6, "routes.1.name",
     "route names must be unique"),
    ("lcm: {url: udpm://x}\n", 1, "routes", "Field required"),
    ("routes: [\n", 2, "", "not valid YAML"),
]  # fmt: skip


@pytest.mark.parametrize(("text", "line", "field", "reason"), BROKEN_CONFIGS)
def test_a_broken_config_exits_2_naming_file_line_and_field(
    tmp_path: Path, text: str, line: int, field: str, reason: str
) -> None:
    path = write_config(tmp_path, text)
    result = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "run", "-c", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert f"{path}:{line}: {field}" in result.stderr and reason in result.stderr, result.stderr
    with pytest.raises(ConfigError):
        load_config(path)


CAMERA_ROUTE = """
lcm: {{url: "{url}"}}
foxglove: {{port: 0}}
routes:
  - name: camera
    source: {{transport: lcm, name: "DRAKE_RGBD_CAMERA_IMAGES(_.*)?"}}
    translator: {translator}
    destination: {{transport: {destination}, name: "/camera{{1:path}}"}}
    options: {options}
"""


@pytest.mark.parametrize(
    ("translator", "destination", "options", "missing"),
    [
        ("drake_images_to_foxglove", "foxglove", "{}", "foxglove.RawImage"),
        ("drake_images_to_ros", "ros", "{camera_info: {width: 64, height: 48, fov_y: 45}}", "sensor_msgs/msg/CameraInfo"),
    ],
)  # fmt: skip
def test_a_camera_route_whose_interface_is_missing_is_refused_at_start_in_one_line(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    translator: str,
    destination: str,
    options: str,
    missing: str,
) -> None:
    """A camera's outputs are its ports', known from its images; what it may write is declared
    from its options, so the start-up check refuses before the first image (here: CameraInfo,
    written only because the options ask for it)."""
    from viewer_bridge.cli import main as cli
    from viewer_bridge.transports import foxglove, ros2

    schema, message_class = foxglove.schema, ros2.message_class

    def without(name: str, lookup: Any) -> Any:
        def look(type_name: str) -> Any:
            if type_name == name:
                raise (KeyError if lookup is schema else ImportError)(f"{name} made unavailable by the test")
            return lookup(type_name)

        return look

    monkeypatch.setattr(foxglove, "schema", without(missing, schema))
    monkeypatch.setattr(ros2, "message_class", without(missing, message_class))
    text = CAMERA_ROUTE.format(url=lcm_url(), translator=translator, destination=destination, options=options)
    path = write_config(tmp_path, text)
    assert cli.main(["run", "-c", str(path), "--duration", "0.1"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith("viewer-bridge run: ") and missing in error and "\n" not in error, error


# --- lazy routes ------------------------------------------------------------------------------------------


def test_lazy_routes_translate_only_while_someone_listens(probe: RosProbe, tmp_path: Path) -> None:
    """The default config's TF and marker routes are lazy: nothing is translated for them until a
    subscriber appears, which then gets the model and the latest transforms at once."""
    from viewer_bridge.examples.scenes import draw_of, small_scene
    from viewer_bridge.formats.drake.load import load_from_scene

    url = lcm_url(10)
    stats_path = tmp_path / "stats.json"
    bridge = BridgeProcess("--lcm-url", url, "--stats-json", str(stats_path), "--stats-period", "0.2")
    bus = LcmBus(url)
    scene = small_scene()
    lazy = ("tf", "link_markers", "markers")

    def draws(seconds: float, start: float) -> None:
        for index in range(int(seconds * 50)):
            bus.publish("DRAKE_VIEWER_DRAW", draw_of(scene, start + index / 50))
            time.sleep(0.02)

    def stats() -> dict[str, Any]:
        return json.loads(stats_path.read_text())["routes"] if stats_path.exists() else {}  # type: ignore[no-any-return]

    try:
        bridge.wait_for_line(" running (")
        bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode())  # the only load
        draws(1.0, 0.0)
        # Every draw is in and accounted for (the stats file is rewritten every 0.2 s).
        assert probe.wait_for(lambda: all(_settled(stats().get(name), 50) for name in (*lazy, "poses"))), (
            stats()
        )
        idle = stats()
        assert {idle[name]["state"] for name in lazy} == {"idle: no subscriber"}, idle
        for name in lazy:  # draws flowed in, nothing went out (a draw conflated by `latest` is a drop)
            route = idle[name]
            assert route["messages_in"] >= 50 and route["messages_out"] == 0, (name, route)
            assert route["idle_skipped"] + route["dropped"] + route["queued"] == route["messages_in"], (
                name,
                route,
            )
        # not lazy: publishes
        assert idle["poses"]["messages_in"] >= 50 and idle["poses"]["messages_out"] >= 1
        # Subscribers join while nothing is sent: they get the model (from the load the routes
        # skipped) and the last draw's transforms at once, then the draws that follow.
        link_markers = probe.subscribe("/drake/link_markers", "visualization_msgs/msg/MarkerArray", 10,
                                       latched=True)  # fmt: skip
        markers = probe.subscribe("/drake/markers", "visualization_msgs/msg/MarkerArray", 10, latched=True)
        tf = probe.subscribe("/tf", "tf2_msgs/msg/TFMessage")
        assert probe.wait_for(lambda: bool(link_markers) and bool(markers) and bool(tf)), bridge.lines
        assert [_tip_z(message) for message in tf] == [0.98]  # the last draw before anyone listened
        draws(1.0, 10.0)
        assert probe.wait_for(lambda: _tip_z(tf[-1]) == 10.98)
        assert probe.wait_for(lambda: all(_active(stats().get(name), 100) for name in lazy)), stats()
        active = stats()
    finally:
        assert bridge.stop() == 0
        bus.close()
    for array in (link_markers[0], markers[0]):
        assert array.markers[0].action == 3  # DELETEALL: the load's full array came first
        assert len([m for m in array.markers if m.action == 0]) == 2
    assert {m.header.frame_id for m in link_markers[0].markers[1:]} == {"plant/robot/base", "plant/robot/tip"}
    assert all(_tip_z(message) >= 10 for message in tf[1:])
    assert {active[name]["state"] for name in lazy} == {"active"}, active
    assert all(active[name]["errors"] == {} for name in lazy), active
    # Stats lines: two decimals, or "-" for a route with no samples yet.
    latencies = [
        re.search(r"latency p50 (\S+) p99 (\S+) ms", line) for line in bridge.lines if "route " in line
    ]
    values = [value for match in latencies if match for value in match.groups()]
    assert "-" in values and all(value == "-" or re.fullmatch(r"\d+\.\d\d", value) for value in values), (
        values
    )


def _tip_z(message: Any) -> float:
    """The z of plant/robot/tip in a TFMessage of `draw_of` (it is the draw's time in seconds)."""
    (tip,) = [t for t in message.transforms if t.child_frame_id == "plant/robot/tip"]
    return round(float(tip.transform.translation.z), 6)


def test_ros_args_are_passed_to_rclpy_like_any_node(probe: RosProbe, tmp_path: Path) -> None:
    from rclpy.parameter_client import AsyncParameterClient

    from viewer_bridge.examples.scenes import draw_of, small_scene

    url = lcm_url(14)
    bridge = BridgeProcess(
        "--lcm-url", url, "--set", "time=sim", "--ros-args", "-r", "__ns:=/sim1", "-p", "use_sim_time:=true"
    )
    bus = LcmBus(url)
    poses = probe.subscribe("/sim1/drake/poses", "geometry_msgs/msg/PoseArray")
    try:
        bridge.wait_for_line(" running (")
        assert "ROS 2 node /sim1/viewer_bridge" in bridge.wait_for_line(" running (")

        def sent() -> bool:
            bus.publish("DRAKE_VIEWER_DRAW", draw_of(small_scene(), 1.5))
            return bool(poses)

        assert probe.wait_for(sent, timeout=20), bridge.lines
        client = AsyncParameterClient(probe.node, "/sim1/viewer_bridge")
        assert client.wait_for_services(timeout_sec=10)
        future = client.get_parameters(["use_sim_time"])
        assert probe.wait_for(future.done)
        assert future.result().values[0].bool_value is True
    finally:
        assert bridge.stop() == 0
        bus.close()
    assert _stamp_ms(poses[0].header.stamp) == 1500


# --- pieces ----------------------------------------------------------------------------------------------


def test_default_config_is_printed_and_valid() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "run", "--print-default-config"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0 and result.stdout == DEFAULT_CONFIG
    config = load_config(None)
    assert [route.name for route in config.routes] == [
        "tf",
        "link_markers",
        "markers",
        "poses",
        "shapes",
        "deformable",
        "point_cloud",
        "draw_frames",
        "point_cloud_from_ros",
        "camera_images",
        "camera_images_unnamed",
        "camera_image_from_ros",
        "contact_markers",
        "contact_wrenches",
        "tree_viewer",
        "foxglove_scene",
        "foxglove_transforms",
        "foxglove_camera_images",
        "foxglove_camera_images_unnamed",
        "lcm_bus",
        "foxglove_lcm_bus",
        "lcm_in",
        "foxglove_lcm_in",
    ]


@pytest.mark.parametrize(
    ("channel", "template", "name"),
    [
        ("DRAKE_VIEWER_DRAW", "/drake{1:path}/poses", "/drake/poses"),
        ("DRAKE_VIEWER_DRAW_PROXIMITY", "/drake{1:path}/poses", "/drake/proximity/poses"),
        ("SIM2_DRAKE_VIEWER_DRAW_PROXIMITY", "/{1:lower}/{2}", "/sim2/_PROXIMITY"),
        ("9 lives!_DRAKE_VIEWER_DRAW_PROXIMITY", "/{1:topic}{2:path}", "/n9_lives_/proximity"),
    ],
)
def test_destination_templates(channel: str, template: str, name: str) -> None:
    import re

    pattern = re.compile(r"(?:(.+?)_)?DRAKE_VIEWER_DRAW(_PROXIMITY)?" if "{2" in template else
                         r"DRAKE_VIEWER_DRAW(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?")  # fmt: skip
    match = pattern.fullmatch(channel)
    assert match is not None and destination_name(template, match) == name


# --- 6. convert to MCAP ------------------------------------------------------------------------------------


def test_convert_writes_an_mcap_that_reads_back(drake_log: Path, tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from viewer_bridge.transports.lcm import read_log

    out = tmp_path / "drake.mcap"
    result = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "convert", str(drake_log), str(out)],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    assert "/drake/illustration/markers" in result.stdout
    events_read = list(read_log(drake_log, "DRAKE_VIEWER_DRAW_ILLUSTRATION"))
    events = [drake_lcmtypes.lcmt_viewer_draw.decode(e.data) for e in events_read]
    draws = {event.timestamp_us: draw for event, draw in zip(events_read, events, strict=True)}
    topics: dict[str, list[Any]] = {}
    with out.open("rb") as file:
        for _, channel, _, message in make_reader(
            file, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages():
            topics.setdefault(channel.topic, []).append(message)
    poses = topics["/drake/illustration/poses"]
    assert len(poses) == len(events)
    for message in poses:
        # stamped with the log's receive time (time: receive, as /tf)
        draw = draws[message.header.stamp.sec * 1_000_000 + message.header.stamp.nanosec // 1000]
        assert [[p.position.x, p.position.y, p.position.z] for p in message.poses] == [
            list(p) for p in draw.position
        ]
        assert [
            [p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z] for p in message.poses
        ] == [list(q) for q in draw.quaternion]
    markers = topics["/drake/illustration/markers"]
    assert markers[0].markers[0].action == 3 and len(markers) == len(events) + 1
    assert {p.type for p in topics["/drake/illustration/shapes/primitives"]} == {1, 2, 3}
    assert len(topics["/drake/proximity/shapes/meshes"]) >= 6  # capsule, ellipsoid, meshes as shape_msgs/Mesh


def test_clock_carries_drakes_sim_time() -> None:
    from rclpy.serialization import deserialize_message
    from rosgraph_msgs.msg import Clock

    from viewer_bridge.translators.registry import TRANSLATORS

    names = ("plant::a",)
    draw = DrawEncoder().encode(
        LinkPoses(61_250, names, np.ones(1, np.int32), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]))
    )
    ((_, data),) = TRANSLATORS["drake_to_clock"]({}).translate(Received("DRAKE_VIEWER_DRAW", draw))
    clock = deserialize_message(data, Clock).clock
    assert (clock.sec, clock.nanosec) == (61, 250_000_000)


def test_a_log_replays_through_the_routes_and_the_bridge_stops_at_its_end(
    drake_log: Path, tmp_path: Path
) -> None:
    from viewer_bridge.transports.lcm import read_log

    stats = tmp_path / "stats.json"
    config = write_config(tmp_path, EVERY_DRAW.replace("DRAKE_VIEWER_DRAW", "DRAKE_VIEWER_DRAW_ILLUSTRATION"))
    result = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "run", "-c", str(config), "--lcm-url", f"file://{drake_log}?speed=0",
         "--stats-json", str(stats)],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    route = json.loads(stats.read_text())["routes"]["poses"]
    draws = len(list(read_log(drake_log, "DRAKE_VIEWER_DRAW_ILLUSTRATION")))
    assert route["messages_in"] == route["messages_out"] == draws and route["errors"] == {}


def test_a_router_loads_its_lcm_types_once_naming_a_refused_type(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The config's lcm_types are loaded when the router is made (one library for its transports and
    translators); a recursive type is named once; a bad source stops the start with a BridgeError."""
    from tests.translators.test_lcm_generic import CORPUS
    from viewer_bridge.config.bridge import BridgeConfig
    from viewer_bridge.errors import BridgeError
    from viewer_bridge.router.router import Router

    routes = [{"name": "bus", "source": {"transport": "lcm", "name": "(.*)"}, "translator": "lcm_to_ros",
               "destination": {"transport": "mcap", "name": "/lcm/{1:topic}"}}]  # fmt: skip
    config = BridgeConfig.model_validate({"lcm": {"url": "memq://"}, "mcap": {"path": str(tmp_path / "out.mcap")},
                                          "lcm_types": [str(CORPUS)], "routes": routes})  # fmt: skip
    with caplog.at_level("WARNING", logger="viewer_bridge"):
        router = Router(config)
    router.close()
    named = [
        record.getMessage() for record in caplog.records if "vbtest_lab.tree_node_t" in record.getMessage()
    ]
    assert len(named) == 1 and "contains itself" in named[0]
    assert (
        router.shared.lcm_types.get("vbtest_lab.arm_status_t").ros_type
        == "vbtest_lab_lcm_msgs/msg/ArmStatusT"
    )
    assert router.routes[0].prototype is not None and router.routes[0].prototype.shared is router.shared
    broken = tmp_path / "broken.lcm"
    broken.write_text("struct broken_t { int32_t a }\n")
    with pytest.raises(BridgeError, match="broken.lcm"):  # before any transport is made
        Router(config.model_copy(update={"lcm_types": [str(broken)]}))
