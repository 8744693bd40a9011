"""ROS 2 inputs whose QoS follows the publishers, end to end with real rclpy peers over DDS: a
best-effort publisher (as sensor drivers publish, `SensorDataQoS`) and a transient-local one that
published once before the bridge started (as `/robot_description` is) both reach LCM, decoded
exactly by lcm-gen's classes; a best-effort publisher joining a topic carried reliable keeps both
flowing, none twice; a best-effort command publisher reaches LCM; a route whose config forces a
QoS no publisher offers counts `qos_incompatible`. And the hostile side: a stalled bridge sends no
old command, and a peer advertising thousands of command topics no channel allows costs nothing."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import psutil
import pytest
from rclpy.qos import QoSProfile

from tests.lcmcodec.ros_bag import lcmgen_decode
from tests.lcmcodec.test_from_ros import lcm_gen_all
from tests.peers import BridgeProcess, RosProbe, wait_for, write_config
from tests.test_commands import command
from tests.test_lcm_in import ros_from_lcm
from tests.test_ros_topics import JOINT_STATE, JOINTS, ros_message, without_lengths
from tests.test_router import LcmRecorder
from tests.zenoh_peers import free_lcm_url, stats_flags, stats_of
from viewer_bridge.cli.main import main
from viewer_bridge.transports.ros2 import message_class, qos_profile

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

STRING = "std_msgs/msg/String"
IIWA_COMMAND = "drake_lcm_msgs/msg/LcmtIiwaCommand"


def profile(depth: int, reliable: bool = True, latched: bool = False) -> QoSProfile:
    return qos_profile(depth, reliable, latched)  # what a peer publishes with: KEEP_LAST, these policies


SENSOR_DATA = profile(5, reliable=False)  # rclpy's qos_profile_sensor_data


@pytest.fixture(scope="module")
def lcmgen_python(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """lcm-gen's Python of the `.lcm` files `lcm-types generate --ros-types` writes for JointState and String."""
    folder = tmp_path_factory.mktemp("ros_qos_types")
    assert main(["lcm-types", "generate", "--ros-types", JOINT_STATE, STRING, "-o", str(folder / "lcm")]) == 0
    done = lcm_gen_all(folder / "lcm", folder / "gen")
    assert done.returncode == 0, done.stderr
    return folder / "gen" / "py"


def test_best_effort_and_latched_publishers_reach_lcm(lcmgen_python: Path, tmp_path: Path) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    probe = RosProbe("qos_publishers")
    # Published once, before the bridge exists: only a transient-local subscription can get it.
    latched = probe.publisher("/probe/description", STRING, profile(1, latched=True))
    description = ros_message(STRING, {"data": "<robot name='arm'/>"})
    latched.publish(description)
    bridge = BridgeProcess("--lcm-url", url, "--ros-topics", "/probe/.*", *stats_flags(stats))
    try:
        bridge.wait_for_line(" running (")
        sensor = probe.publisher("/probe/joints", JOINT_STATE, SENSOR_DATA)
        assert probe.wait_for(lambda: sensor.get_subscription_count() >= 1, 90), bridge.lines[-10:]

        def carried() -> bool:
            sensor.publish(ros_message(JOINT_STATE, JOINTS))  # best effort: until one arrives
            return "probe/joints" in recorder.messages

        assert wait_for(carried, 60), bridge.lines[-10:]
        assert wait_for(lambda: "probe/description" in recorder.messages, 60), bridge.lines[-10:]
        recorder.sync()
        assert len(recorder.messages["probe/description"]) == 1  # once, though it was re-subscribed
        decoded = lcmgen_decode(
            lcmgen_python,
            [("sensor_msgs.JointState", recorder.messages["probe/joints"][0]),
             ("std_msgs.String", recorder.messages["probe/description"][0])],
        )  # fmt: skip
        assert without_lengths(decoded[0]) == JOINTS
        assert decoded[1] == {"data": "<robot name='arm'/>"}
        route = stats_of(stats)["ros_topics_ros"]
        assert route["qos_incompatible"] == 0 and route["errors"] == {}
        assert not any("incompatible QoS" in line for line in bridge.lines)  # rmw's own warning, never
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def test_a_best_effort_publisher_joining_a_reliable_topic_keeps_both_flowing(tmp_path: Path) -> None:
    url = free_lcm_url()
    recorder = LcmRecorder(url)
    probe = RosProbe("qos_joining")
    bridge = BridgeProcess("--lcm-url", url, "--ros-topics", "/probe/shared")
    try:
        bridge.wait_for_line(" running (")
        reliable = probe.publisher("/probe/shared", STRING, profile(10))
        assert probe.wait_for(lambda: reliable.get_subscription_count() >= 1, 90), bridge.lines[-10:]
        sent: list[str] = []

        def publish(publisher: Any, text: str) -> None:
            sent.append(text)
            publisher.publish(ros_message(STRING, {"data": text}))

        publish(reliable, "reliable 0")
        assert wait_for(lambda: len(recorder.messages.get("probe/shared", [])) >= 1, 60)
        best_effort = probe.publisher("/probe/shared", STRING, SENSOR_DATA)
        # The bridge subscribes anew, best effort, within seconds; the reliable publisher goes on.
        assert wait_for(lambda: any("subscribed anew" in line for line in bridge.lines), 60), bridge.lines[
            -10:
        ]
        assert probe.wait_for(lambda: best_effort.get_subscription_count() >= 1, 60)
        for index in range(1, 40):
            publish(reliable, f"reliable {index}")
            publish(best_effort, f"best effort {index}")
            time.sleep(0.05)
        recorder.sync()
        texts = [decoded["data"] for decoded in lcmgen_strings(recorder.messages.get("probe/shared", []))]
        assert len(texts) == len(set(texts))  # none twice, though two subscriptions overlapped
        assert {f"reliable {index}" for index in range(40)} <= set(texts)  # reliable: every one
        assert any(text.startswith("best effort") for text in texts)
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def lcmgen_strings(messages: list[bytes]) -> list[dict[str, Any]]:
    """`std_msgs/String` as the bridge carries it to LCM: a u64 fingerprint, an int32 length
    (with the NUL), the bytes, the NUL (LCM's string encoding)."""
    decoded = []
    for data in messages:
        length = int.from_bytes(data[8:12], "big")
        decoded.append({"data": data[12 : 12 + length - 1].decode()})
    return decoded


def test_a_best_effort_command_publisher_reaches_lcm(tmp_path: Path) -> None:
    url = free_lcm_url()
    recorder = LcmRecorder(url)
    probe = RosProbe("qos_commander")
    bridge = BridgeProcess("--lcm-url", url, "--allow-commands", "IIWA_COMMAND")
    try:
        bridge.wait_for_line(" running (")
        publisher = probe.publisher("/lcm_in/IIWA_COMMAND", IIWA_COMMAND, SENSOR_DATA)
        assert probe.wait_for(lambda: publisher.get_subscription_count() >= 1, 90), bridge.lines[-10:]
        sent = command("IIWA_COMMAND", 7)

        def commanded() -> bool:
            publisher.publish(ros_from_lcm(sent, message_class(IIWA_COMMAND)))
            return "IIWA_COMMAND" in recorder.messages

        assert wait_for(commanded, 60), bridge.lines[-10:]
        assert recorder.messages["IIWA_COMMAND"][0] == sent.encode()  # as lcm-gen encodes it
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


FORCED = """
routes:
  - name: forced
    source: {transport: ros, name: /probe/forced_cloud}
    translator: ros_point_cloud_to_drake
    destination: {transport: lcm, name: FORCED_CLOUD}
    qos: {reliability: reliable}
"""


def test_a_qos_the_config_forces_is_counted_and_said_when_no_publisher_offers_it(tmp_path: Path) -> None:
    stats = tmp_path / "stats.json"
    config = write_config(tmp_path, FORCED)
    probe = RosProbe("qos_forced")
    bridge = BridgeProcess("-c", str(config), "--lcm-url", free_lcm_url(), "-q", *stats_flags(stats))
    try:
        assert wait_for(lambda: "forced" in stats_of(stats), 90), bridge.lines[-10:]
        probe.publisher("/probe/forced_cloud", "sensor_msgs/msg/PointCloud2", SENSOR_DATA)
        assert wait_for(lambda: stats_of(stats).get("forced", {}).get("qos_incompatible", 0) >= 1, 60)
        said = [line for line in bridge.lines if "qos_incompatible" in line]
        assert len(said) == 1, bridge.lines[-10:]  # said once, in the bridge's words, with the fix
        assert "reliability does not match" in said[0] and "qos.reliability" in said[0]
    finally:
        probe.close()
        assert bridge.stop() == 0


def test_a_stalled_bridge_sends_no_old_command(tmp_path: Path) -> None:
    """Commands at 50 Hz while the bridge is stopped (SIGSTOP) for 2 s: on LCM, none arrives older
    than max_age_ms (200 ms) by the time it was sent, and of those sent during the stall at most
    one goes out (the command subscription keeps one: KEEP_LAST 1)."""
    url = free_lcm_url()
    arrivals: list[tuple[int, float]] = []  # (utime the command carries: its send time, when it came)
    recorder = LcmRecorder(url)
    recorder.bus.subscribe("IIWA_COMMAND", lambda _c, data, _r: arrivals.append(
        (drake_lcmtypes.lcmt_iiwa_command.decode(bytes(data)).utime, time.time())))  # fmt: skip
    probe = RosProbe("qos_stall")
    bridge = BridgeProcess("--lcm-url", url, "--allow-commands", "IIWA_COMMAND")
    try:
        bridge.wait_for_line(" running (")
        publisher = probe.publisher("/lcm_in/IIWA_COMMAND", IIWA_COMMAND, profile(10))
        assert probe.wait_for(lambda: publisher.get_subscription_count() >= 1, 90), bridge.lines[-10:]

        def send_for(seconds: float) -> None:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                sent = command("IIWA_COMMAND", time.time_ns() // 1000)
                publisher.publish(ros_from_lcm(sent, message_class(IIWA_COMMAND)))
                time.sleep(0.02)

        send_for(2.0)
        assert wait_for(lambda: len(arrivals) > 0, 30)
        stalled_at = time.time_ns() // 1000
        os.kill(bridge.process.pid, signal.SIGSTOP)
        try:
            send_for(2.0)
        finally:
            resumed_at = time.time_ns() // 1000
            os.kill(bridge.process.pid, signal.SIGCONT)
        send_for(2.0)
        recorder.sync()
        ages_ms = sorted((came - utime / 1e6) * 1e3 for utime, came in arrivals)
        assert ages_ms and ages_ms[-1] <= 200 + 50, ages_ms[-5:]  # each within its limit (+ LCM's hop)
        # What was sent while the bridge stood still goes out as one command at the most: the newest.
        assert sum(stalled_at <= utime <= resumed_at for utime, _ in arrivals) <= 1
        assert arrivals[-1][0] > resumed_at  # and the commands after it flow again
    finally:
        probe.close()
        os.kill(bridge.process.pid, signal.SIGCONT)
        assert bridge.stop() == 0
        recorder.close()


def test_thousands_of_disallowed_command_topics_cost_nothing(tmp_path: Path) -> None:
    """A peer advertising 3,000 `/lcm_in/...` topics of a command type, none allowed: the bridge
    subscribes to none (no per-topic state), its memory grows by less than 64 MiB, and once the
    peer is gone its CPU goes back under 5% of a core."""
    probe = RosProbe("qos_spam")
    bridge = BridgeProcess("--lcm-url", free_lcm_url(), "--allow-commands", "IIWA_COMMAND")
    process = psutil.Process(bridge.process.pid)
    try:
        bridge.wait_for_line(" running (")
        allowed = probe.publisher("/lcm_in/IIWA_COMMAND", IIWA_COMMAND)
        assert probe.wait_for(lambda: allowed.get_subscription_count() >= 1, 90)  # discovery is up
        before = process.memory_info().rss
        spam = [probe.publisher(f"/lcm_in/SPAMC_{index}", IIWA_COMMAND) for index in range(3000)]
        time.sleep(15)  # long enough for several discovery passes over all 3,000 (none subscribed)
        assert all(each.get_subscription_count() == 0 for each in spam[::100])
        grown = process.memory_info().rss - before
        assert grown < 64 * 2**20, grown
        for each in spam:
            probe.node.destroy_publisher(each)
        process.cpu_percent()

        def idle() -> bool:
            time.sleep(2)
            return process.cpu_percent() < 5.0

        assert wait_for(idle, 120), process.cpu_percent()
    finally:
        probe.close()
        assert bridge.stop() == 0


# --- Zenoh -------------------------------------------------------------------------------------------


@pytest.fixture
def zenoh_router() -> Any:
    from tests.zenoh_peers import Router

    router = Router()
    yield router
    router.close()


def test_over_zenoh_best_effort_and_latched_publishers_reach_lcm(zenoh_router: Any, tmp_path: Path) -> None:
    """The rmw_zenoh-format peer publishes as rmw_zenoh does: a transient-local String once, before
    the bridge starts (an advanced publisher with a cache), and a best-effort JointState; both reach
    LCM, the latched one once."""
    from rclpy.serialization import serialize_message

    from tests.test_ros_topics import ZENOH_JOINTS
    from tests.zenoh_peers import RmwZenohPeer

    url = free_lcm_url()
    recorder = LcmRecorder(url)
    peer = RmwZenohPeer(zenoh_router.endpoint, 45, node="qos_zenoh_peer")
    latched = peer.publisher("/probe/description", STRING, entity=1, depth=1, latched=True)
    latched(bytes(serialize_message(ros_message(STRING, {"data": "<robot name='arm'/>"}))))
    bridge = BridgeProcess(
        "-c", "builtin:zenoh", "--lcm-url", url, "--ros-topics", "/probe/.*",
        "--set", f"zenoh.connect=[{zenoh_router.endpoint}]", "--set", "zenoh.domain_id=45",
    )  # fmt: skip
    try:
        bridge.wait_for_line(" running (")
        sensor = peer.publisher("/probe/joints", JOINT_STATE, entity=2, depth=5, best_effort=True)
        joints = bytes(serialize_message(ros_message(JOINT_STATE, ZENOH_JOINTS)))
        assert wait_for(lambda: peer.subscribed("/probe/joints"), 90), bridge.lines[-10:]

        def carried() -> bool:
            sensor(joints)
            return "probe/joints" in recorder.messages

        assert wait_for(carried, 60), bridge.lines[-10:]
        assert wait_for(lambda: "probe/description" in recorder.messages, 60), bridge.lines[-10:]
        recorder.sync()
        assert lcmgen_strings(recorder.messages["probe/description"]) == [{"data": "<robot name='arm'/>"}]
    finally:
        peer.close()
        assert bridge.stop() == 0
        recorder.close()


def test_a_latched_message_published_before_the_bridge_reaches_a_route_subscribed_at_start(
    tmp_path: Path,
) -> None:
    """`/drake_in/point_cloud` is subscribed as the bridge starts, before discovery has found any
    publisher (so with the route's own QoS, volatile); the transient-local publisher found then
    calls for a new subscription, whose history brings the cloud published before the bridge
    started: it reaches LCM once."""
    import numpy as np
    from sensor_msgs.msg import PointCloud2, PointField

    url = free_lcm_url()
    recorder = LcmRecorder(url)
    probe = RosProbe("qos_latched_cloud")
    cloud = PointCloud2()
    cloud.header.frame_id = "camera_link"
    cloud.height, cloud.width = 1, 3
    cloud.fields = [PointField(name=name, offset=4 * index, datatype=PointField.FLOAT32, count=1)
                    for index, name in enumerate("xyz")]  # fmt: skip
    cloud.point_step, cloud.row_step, cloud.is_dense = 12, 36, True
    cloud.data = np.arange(9, dtype="<f4").tobytes()
    publisher = probe.publisher(
        "/drake_in/point_cloud", "sensor_msgs/msg/PointCloud2", profile(1, latched=True)
    )
    publisher.publish(cloud)
    bridge = BridgeProcess("--lcm-url", url)
    try:
        bridge.wait_for_line(" running (")
        assert wait_for(lambda: "DRAKE_POINT_CLOUD_FROM_ROS" in recorder.messages, 60), bridge.lines[-10:]
        time.sleep(3)  # the old subscription's last second and the switch's window: nothing more comes
        recorder.sync()
        assert len(recorder.messages["DRAKE_POINT_CLOUD_FROM_ROS"]) == 1
        received = drake_lcmtypes.lcmt_point_cloud.decode(recorder.messages["DRAKE_POINT_CLOUD_FROM_ROS"][0])
        assert (received.width, received.frame_name) == (3, "camera_link")
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()


def test_many_mixed_publishers_and_one_that_flaps_cost_at_most_two_subscriptions(tmp_path: Path) -> None:
    """100 publishers of one topic with every mix of QoS, then one whose QoS changes every half
    second: the bridge never holds more than two subscriptions on the topic (the live one and, for
    a second, the one it replaces), and every kind of publisher is heard."""
    url = free_lcm_url()
    recorder = LcmRecorder(url)
    probe = RosProbe("qos_crowd")
    bridge = BridgeProcess("--lcm-url", url, "--ros-topics", "/probe/crowd")
    kinds = [profile(1 + index % 7, reliable=index % 2 == 0, latched=index % 3 == 0) for index in range(100)]
    try:
        bridge.wait_for_line(" running (")
        crowd = [probe.publisher("/probe/crowd", STRING, kind) for kind in kinds]
        most = 0
        deadline = time.monotonic() + 8
        flapping = None
        while time.monotonic() < deadline:  # a publisher that comes back with other QoS, twice a second
            if flapping is not None:
                probe.node.destroy_publisher(flapping)
            flapping = probe.publisher(
                "/probe/crowd", STRING, profile(5, reliable=bool(int(time.monotonic() * 2) % 2))
            )
            most = max(most, probe.node.count_subscribers("/probe/crowd"))
            time.sleep(0.5)
        assert 1 <= most <= 2, most

        def heard(index: int) -> bool:
            crowd[index].publish(ros_message(STRING, {"data": f"from {index}"}))
            return any(f"from {index}".encode() in data for data in recorder.messages.get("probe/crowd", []))

        assert wait_for(lambda: heard(1), 60)  # best effort, volatile
        assert wait_for(lambda: heard(0), 60)  # reliable, transient local
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()
