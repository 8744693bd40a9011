"""The ign-transport node against the real peer, Debian's `ign-transport-topic` (transport 11), and
against itself: the package of type names, a publisher with topic statistics (version 110)."""

from __future__ import annotations

import os
import socket
import struct
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest
import zmq

from tests.conftest import DRAKE_SCENE_SCRIPT, lcm_url
from tests.formats.ign.oracle import pose_v
from tests.peers import BridgeProcess
from tests.test_router import LcmRecorder
from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.model.scene import LinkPoses
from viewer_bridge.transports.base import PROTOBUF, MessageType, Qos
from viewer_bridge.transports.ign import IgnNode, IgnSettings, IgnTransport
from viewer_bridge.transports.ign_discovery import WIRE_VERSION
from viewer_bridge.transports.ign_environment import DISCOVERY_GROUP, MESSAGE_PORT, NodeEnvironment

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

CLI = "/usr/libexec/ignition/transport11/ign-transport-topic"


@pytest.fixture(autouse=True)
def ign_environment(monkeypatch: pytest.MonkeyPatch) -> str:
    """A partition of this test's own on the loopback interface, for us and the CLI alike."""
    partition = f"vbtest{os.getpid()}_{uuid.uuid4().hex[:6]}"
    monkeypatch.setenv("IGN_PARTITION", partition)
    monkeypatch.setenv("IGN_IP", "127.0.0.1")
    assert Path(CLI).is_file(), "install Debian's ignition-transport-cli (./dev test does)"
    return partition


def cli(*args: str, timeout: float = 60.0) -> str:
    result = subprocess.run(
        [CLI, *args], capture_output=True, text=True, timeout=timeout, env=dict(os.environ)
    )
    return result.stdout


def poses(timestamp_ms: int = 1500) -> LinkPoses:
    return LinkPoses(
        timestamp_ms,
        ("plant::a",),
        np.zeros(1, np.int32),
        np.array([[1.0, 2, 3]]),
        np.array([[1.0, 0, 0, 0]]),
    )


# --- 1. Drake -> bridge -> ign topics, seen by the C++ CLI ----------------------------------------------


def test_the_cli_lists_and_echoes_what_a_drake_simulation_becomes(tmp_path: Path) -> None:
    url = lcm_url(7)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("-c", "builtin:ign", "--lcm-url", url)
    drake = None
    try:
        bridge.wait_for_line(" running (")
        drake = subprocess.Popen([sys.executable, str(DRAKE_SCENE_SCRIPT), url, str(tmp_path), "8"])
        deadline = time.monotonic() + 60
        while "DRAKE_VIEWER_DRAW_ILLUSTRATION" not in recorder.messages and time.monotonic() < deadline:
            time.sleep(0.1)
        topics = ""
        while "/drake/illustration/pose_v" not in topics and time.monotonic() < deadline:
            topics = cli("-l")
        model = cli("-e", "-t", "/drake/illustration/model_v", "-n", "1")
        pose_v = cli("-e", "-t", "/drake/illustration/pose_v", "-n", "1")
    finally:
        if drake is not None:
            drake.kill()
            drake.wait()
        assert bridge.stop() == 0
        recorder.close()
    assert {"/drake/illustration/model_v", "/drake/illustration/pose_v", "/drake/proximity/model_v"} <= set(
        topics.split()
    )
    for text in ("plant::robot0::body3", "type: CAPSULE", "type: ELLIPSOID", "type: CYLINDER", "type: MESH"):
        assert text in model, text
    assert "capsule {\n" in model and "radius: 0.03" in model  # Drake's Capsule(0.03, 0.2)
    names = [line.split('"')[1] for line in pose_v.splitlines() if line.strip().startswith("name:")]
    load = drake_lcmtypes.lcmt_viewer_draw.decode(recorder.messages["DRAKE_VIEWER_DRAW_ILLUSTRATION"][-1])
    assert names == list(load.link_name)  # every link, in the draw's order


# --- 2. the CLI publishes Pose_V -> LCM draw -------------------------------------------------------------


@pytest.mark.parametrize("config", ["builtin:ign", "builtin:gz"])  # Fortress's names, read by either
def test_a_pose_v_from_the_cli_arrives_as_a_drake_draw(config: str) -> None:
    url = lcm_url(8)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("-c", config, "--lcm-url", url)
    # The second pose has no orientation, as in the README's example: it means the identity.
    text = 'header { stamp { sec: 3 nsec: 250000000 } } pose { name: "plant::arm" position { x: 1 y: 2 z: 3 } ' \
           'orientation { x: 0 y: 0 z: 0.6 w: 0.8 } } pose { name: "plant::hand" position { x: 1 } }'  # fmt: skip
    try:
        bridge.wait_for_line(" running (")
        deadline = time.monotonic() + 60
        while "DRAKE_VIEWER_DRAW_FROM_IGN" not in recorder.messages and time.monotonic() < deadline:
            cli("-t", "/drake_in/pose_v", "-m", "ignition.msgs.Pose_V", "-p", text)
            time.sleep(0.2)
    finally:
        assert bridge.stop() == 0
        recorder.close()
    draw = drake_lcmtypes.lcmt_viewer_draw.decode(recorder.messages["DRAKE_VIEWER_DRAW_FROM_IGN"][0])
    assert (draw.timestamp, list(draw.link_name)) == (3250, ["plant::arm", "plant::hand"])
    assert [list(p) for p in draw.position] == [[1.0, 2.0, 3.0], [1.0, 0.0, 0.0]]
    assert np.allclose(draw.quaternion, [[0.8, 0.0, 0.0, 0.6], [1.0, 0.0, 0.0, 0.0]])  # w first


# --- 3. peers come and go ------------------------------------------------------------------------------------


def test_publishers_and_cli_peers_can_restart() -> None:
    url = lcm_url(9)
    received: list[float] = []
    node = IgnNode()
    node.subscribe(
        "/drake/pose_v", "ignition.msgs.Pose_V", lambda topic, data, us: received.append(time.monotonic())
    )
    node.start()
    try:
        for _ in range(2):  # the second bridge is a new process: new uuid, new address
            bridge = BridgeProcess("-c", "builtin:ign", "--lcm-url", url, "--demo")
            bridge.wait_for_line(" running (")
            started = time.monotonic()
            deadline = started + 60
            while not any(at > started for at in received) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert any(at > started for at in received), "no Pose_V after the bridge (re)started"
            # The C++ CLI comes and goes too: each new one hears the bridge (it asks with SUBSCRIBE).
            for _ in range(2):
                assert "demo::shapes::box_0" in cli("-e", "-t", "/drake/pose_v", "-n", "1")
            bridge.process.kill()  # no BYE: the node must notice the silence
            bridge.process.wait()
    finally:
        node.close()


# --- 4. bad datagrams and frames ----------------------------------------------------------------------------


def datagram(message: Any) -> bytes:
    body = message.SerializeToString()
    return struct.pack("<H", len(body)) + body


def test_malformed_datagrams_and_frames_are_counted_and_skipped(ign_environment: str) -> None:
    node = IgnNode()
    got: list[bytes] = []
    node.subscribe("/fuzz", "ignition.msgs.Pose_V", lambda topic, data, us: got.append(data))
    node.start()
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    context = zmq.Context()
    publisher = context.socket(zmq.PUB)
    publisher.bind("tcp://127.0.0.1:*")
    address = publisher.getsockopt_string(zmq.LAST_ENDPOINT)
    full = f"@/{ign_environment}@/fuzz"
    try:
        # Advertisements of the subscribed topic at addresses ZMQ cannot connect to: counted, and
        # the node goes on (a ZMQError here once ended the node's thread, and all discovery with it).
        # Sent first, while the node's socket is empty: behind the flood below, UDP may drop them.
        for bad_address in ("garbage", "tcp://", "tcp://127.0.0.1", "tcp://127.0.0.1:99999", "inproc://x"):
            bad_advertise = MESSAGES.Discovery(version=WIRE_VERSION, process_uuid=str(uuid.uuid4()), type=1)
            bad_advertise.pub.topic, bad_advertise.pub.address = full, bad_address
            bad_advertise.pub.msg_pub.msg_type = "ignition.msgs.Pose_V"
            udp.sendto(datagram(bad_advertise), (DISCOVERY_GROUP, MESSAGE_PORT))
        deadline = time.monotonic() + 60
        while node.errors["advertise_address"] < 5 and time.monotonic() < deadline:
            time.sleep(0.02)
        rng = np.random.default_rng(3)
        good_header = MESSAGES.Discovery(version=WIRE_VERSION, process_uuid="fuzzer", type=4)
        for _ in range(300):
            kind = rng.integers(4)
            if kind == 0:  # a length prefix that disagrees with the datagram
                data = datagram(good_header)
                data = struct.pack("<H", len(data) + int(rng.integers(1, 50))) + data[2:]
            elif kind == 1:  # not a Discovery at all
                data = struct.pack("<H", 40) + rng.bytes(40)
            elif kind == 2:  # the wrong wire version
                data = datagram(MESSAGES.Discovery(version=int(rng.integers(0, 9)), process_uuid="x", type=1))
            else:  # random bytes of any length
                data = rng.bytes(int(rng.integers(0, 300)))
            udp.sendto(data, (DISCOVERY_GROUP, MESSAGE_PORT))
        # A publisher that advertises properly, then sends good and bad ZMQ messages.
        advertise = MESSAGES.Discovery(version=WIRE_VERSION, process_uuid=str(uuid.uuid4()), type=1)
        advertise.pub.topic, advertise.pub.address = full, address
        advertise.pub.process_uuid, advertise.pub.node_uuid = advertise.process_uuid, "node"
        advertise.pub.msg_pub.msg_type = "ignition.msgs.Pose_V"
        payload = pose_v(poses()).SerializeToString()
        deadline = time.monotonic() + 60
        while not got and time.monotonic() < deadline:
            udp.sendto(datagram(advertise), (DISCOVERY_GROUP, MESSAGE_PORT))
            publisher.send_multipart([full.encode(), address.encode(), payload, b"ignition.msgs.Pose_V"])
            time.sleep(0.2)
        assert got, "the node never connected to the advertised publisher"
        before = len(got)
        bad = [
            [full.encode(), address.encode(), payload],  # three frames
            [full.encode(), address.encode(), payload, b"ignition.msgs.Pose_V", b"extra"],  # five
            [full.encode(), address.encode(), payload, b"ignition.msgs.Teapot"],  # an unknown type
            [full.encode() + b"x", address.encode(), payload, b"ignition.msgs.Pose_V"],  # prefix match only
        ]
        for frames in bad * 25:
            publisher.send_multipart(frames)
        for _ in range(10):
            publisher.send_multipart([full.encode(), address.encode(), payload, b"ignition.msgs.Pose_V"])
        deadline = time.monotonic() + 60
        while len(got) < before + 10 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(got) == before + 10 and all(data == payload for data in got)
        errors = dict(node.errors)
        assert errors["data_frames"] == 50 and errors["data_type"] == 25 and errors["data_topic"] == 25, (
            errors
        )
        assert (
            errors["discovery_length"] > 0 and errors["discovery_parse"] + errors["discovery_version"] > 0
        ), errors
        assert errors["advertise_address"] == 5, errors
    finally:
        node.close()
        publisher.close()
        context.term()
        udp.close()


# --- 5. names per Gazebo generation ----------------------------------------------------------------------


def test_builtin_gz_lists_its_publishers_with_gz_names() -> None:
    bridge = BridgeProcess("-c", "builtin:gz", "--lcm-url", lcm_url(10), "--demo")
    info = ""
    try:
        bridge.wait_for_line(" running (")
        deadline = time.monotonic() + 60
        while "gz.msgs.Pose_V" not in info and time.monotonic() < deadline:
            info = cli("-i", "-t", "/drake/pose_v")
    finally:
        assert bridge.stop() == 0
    assert "gz.msgs.Pose_V" in info and "ignition.msgs" not in info, info


def test_the_transport_spells_short_names_in_its_package_and_full_names_as_they_are() -> None:
    for package, short, full in (("gz", "gz.msgs.Pose_V", "ignition.msgs.Model"),
                                 ("ignition", "ignition.msgs.Pose_V", "ignition.msgs.Model")):  # fmt: skip
        transport = IgnTransport(IgnSettings(package=package))  # type: ignore[arg-type]
        try:
            transport.publisher("/short", MessageType("Pose_V", PROTOBUF), Qos())
            transport.publisher("/full", MessageType("ignition.msgs.Model", PROTOBUF), Qos())
            transport.subscribe("/in", MessageType("Pose_V", PROTOBUF), Qos(), lambda message: None)
            advertised = transport.node.discovery.advertised
            assert advertised == {
                transport.node.full_name("/short"): short,
                transport.node.full_name("/full"): full,
            }
            assert transport.node.discovery.subscriptions[transport.node.full_name("/in")].msg_type == short
        finally:
            transport.close()


def test_a_node_takes_either_spelling_and_a_publisher_with_topic_statistics(ign_environment: str) -> None:
    """Version 110 discovery and its fifth data frame (stamp, sequence) are read like version 10."""
    got: list[bytes] = []
    subscriber = IgnNode()
    subscriber.subscribe("/spelled", "gz.msgs.Pose_V", lambda topic, data, us: got.append(data))
    subscriber.start()
    publishers = [IgnNode(environment=NodeEnvironment(ign_environment, "127.0.0.1", topic_statistics=True)),
                  IgnNode(environment=NodeEnvironment(ign_environment, "127.0.0.1"))]  # fmt: skip
    for publisher in publishers:
        publisher.start()
    payloads = {b"statistics, ignition": (publishers[0], "ignition.msgs.Pose_V"),
                b"plain, gz": (publishers[1], "gz.msgs.Pose_V")}  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while set(payloads) - set(got) and time.monotonic() < deadline:
            for payload, (publisher, msg_type) in payloads.items():
                publisher.publish("/spelled", payload, msg_type)
            time.sleep(0.1)
    finally:
        for node in (subscriber, *publishers):
            node.close()
    assert set(got) == set(payloads) and not subscriber.errors, (got, subscriber.errors)
    assert publishers[0].discovery.version == 110
