"""The Foxglove transport end to end: a real pydrake simulation, the bridge as a process with
`-c builtin:foxglove`, and a WebSocket client written here from the Foxglove WebSocket protocol
(JSON control messages; binary message data `0x01 | u32 subscription id | u64 time | payload`),
its payloads decoded with foxglove-schemas-protobuf."""

from __future__ import annotations

import json
import re
import socket
import struct
import time
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import pytest
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from websockets.sync.client import ClientConnection, connect

from tests.conftest import lcm_url
from tests.formats import oracle
from tests.peers import BridgeProcess
from tests.test_router import LcmRecorder, start_drake

pytestmark = pytest.mark.slow
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


class FoxgloveClient:
    """A minimal Foxglove WebSocket client: reads advertisements, subscribes, keeps payloads."""

    def __init__(self, port: int) -> None:
        self._connection = connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS)  # type: ignore[arg-type]
        self.ws: ClientConnection = self._connection.__enter__()
        self.channels: dict[str, dict[str, Any]] = {}  # topic -> advertised channel
        self.messages: dict[str, list[bytes]] = {}  # topic -> payloads, in arrival order
        self._topics: dict[int, str] = {}  # subscription id -> topic

    def pump(self, seconds: float, until: Any = None) -> bool:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if until is not None and until():
                return True
            try:
                frame = self.ws.recv(timeout=max(0.01, deadline - time.monotonic()))
            except TimeoutError:
                break
            if isinstance(frame, str):
                message = json.loads(frame)
                if message["op"] == "advertise":
                    self.channels.update({channel["topic"]: channel for channel in message["channels"]})
            elif frame[0] == 0x01:  # message data
                (subscription,) = struct.unpack_from("<I", frame, 1)
                self.messages.setdefault(self._topics[subscription], []).append(bytes(frame[13:]))
        return until is not None and bool(until())

    def subscribe(self, *topics: str) -> None:
        assert self.pump(60, lambda: all(topic in self.channels for topic in topics)), self.channels.keys()
        subscriptions = []
        for topic in topics:
            subscription = len(self._topics) + 1
            self._topics[subscription] = topic
            subscriptions.append({"id": subscription, "channelId": self.channels[topic]["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def close(self) -> None:
        self._connection.__exit__(None, None, None)


def foxglove_port(bridge: BridgeProcess) -> int:
    line = bridge.wait_for_line("routes running")
    match = re.search(r"ws://127\.0\.0\.1:(\d+)", line)
    assert match is not None, line
    return int(match.group(1))


def scene_of(payloads: list[bytes]) -> dict[str, Any]:
    entities: dict[str, Any] = {}
    for payload in payloads:
        update = SceneUpdate()
        update.ParseFromString(payload)
        entities.update({entity.id: entity for entity in update.entities})
    return entities


def check_scene(entities: dict[str, Any], load: Any) -> None:
    """Every link's entity, in its frame, with each geometry's primitive at Drake's sizes."""
    assert set(entities) == {link.name for link in load.link}
    for link in load.link:
        entity = entities[link.name]
        assert entity.frame_id == ("world" if link.name == "world" else link.name.replace("::", "/"))
        assert entity.frame_locked
        geometry = link.geom[0]
        data = list(geometry.float_data)
        kind = {1: "cubes", 2: "spheres", 3: "cylinders", 4: "models", 5: "cylinders", 6: "spheres"}[geometry.type]
        (primitive, *_) = getattr(entity, kind)
        if geometry.type == 4:
            assert primitive.data[:4] == b"glTF" and primitive.media_type == "model/gltf-binary"
            continue
        size = [primitive.size.x, primitive.size.y, primitive.size.z]
        if geometry.type == 1:  # box: full lengths
            expected = data
        elif geometry.type == 2:  # sphere: the diameter on each axis
            expected = [2 * data[0]] * 3
        elif geometry.type == 6:  # ellipsoid: per-axis diameters
            expected = [2 * value for value in data]
        else:  # cylinder and a capsule's cylinder: Drake's [radius, length]
            expected = [2 * data[0], 2 * data[0], data[1]]
        assert oracle.close(size, expected), (link.name, size, expected)
        position = [primitive.pose.position.x, primitive.pose.position.y, primitive.pose.position.z]
        assert oracle.close(position, geometry.position), link.name
        if geometry.type == 5:  # a capsule: the cylinder and a sphere at each end
            assert len(entity.spheres) == 2 and all(oracle.close(
                [s.size.x, s.size.y, s.size.z], [2 * data[0]] * 3) for s in entity.spheres)  # fmt: skip


def test_a_drake_simulation_reaches_a_foxglove_client(tmp_path: Path) -> None:
    url = lcm_url(12)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("-c", "builtin:foxglove", "--lcm-url", url, "--stats-period", "1")
    client = late = None
    try:
        port = foxglove_port(bridge)
        drake = start_drake(url, tmp_path, 3.0)
        # A channel is advertised with its stream's first message; the lazy routes translate
        # once this client subscribes, the load they skipped first.
        client = FoxgloveClient(port)
        client.subscribe("/drake/illustration/scene", "/drake/illustration/transforms")
        assert drake.wait(timeout=120) == 0
        recorder.sync()  # holds Drake's last draw
        draws = recorder.messages["DRAKE_VIEWER_DRAW_ILLUSTRATION"]
        last = drake_lcmtypes.lcmt_viewer_draw.decode(draws[-1])

        def has_last_draw() -> bool:
            payloads = client.messages.get("/drake/illustration/transforms", [])  # type: ignore[union-attr]
            return bool(payloads) and _stamp_ms(_transforms(payloads[-1])) == last.timestamp

        assert client.pump(60, has_last_draw)
        # A client that connects after the load still receives the whole scene.
        late = FoxgloveClient(port)
        late.subscribe("/drake/illustration/scene")
        assert late.pump(60, lambda: bool(late.messages.get("/drake/illustration/scene")))  # type: ignore[union-attr]
    finally:
        for each in (client, late):
            if each is not None:
                each.close()
        assert bridge.stop() == 0
        recorder.close()
    load = drake_lcmtypes.lcmt_viewer_load_robot.decode(recorder.messages["DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION"][0])
    check_scene(scene_of(client.messages["/drake/illustration/scene"]), load)
    check_scene(scene_of(late.messages["/drake/illustration/scene"]), load)
    transforms = _transforms(client.messages["/drake/illustration/transforms"][-1])
    by_child = {t.child_frame_id: t for t in transforms.transforms}
    assert set(by_child) == {name.replace("::", "/") for name in last.link_name}
    for name, position, wxyz in zip(last.link_name, last.position, last.quaternion, strict=True):
        found = by_child[name.replace("::", "/")]
        assert found.parent_frame_id == "world"
        t, r = found.translation, found.rotation
        assert oracle.close([t.x, t.y, t.z], position)
        assert oracle.same_rotation([r.x, r.y, r.z, r.w], oracle.xyzw_of(wxyz))


def _transforms(payload: bytes) -> Any:
    message = FrameTransforms()
    message.ParseFromString(payload)
    return message


def _stamp_ms(message: Any) -> int:
    stamp = message.transforms[0].timestamp
    return int(stamp.seconds) * 1000 + int(stamp.nanos) // 1_000_000


def test_bad_clients_do_not_stop_the_bridge_or_other_clients(tmp_path: Path) -> None:
    from bridge.formats.drake import load_from_scene
    from bridge.transports.lcm import LcmBus
    from tests.test_translators import draw_of, small_scene

    url = lcm_url(13)
    bridge = BridgeProcess("-c", "builtin:foxglove", "--lcm-url", url, "--stats-period", "0.5")
    bus = LcmBus(url)
    good = None
    try:
        port = foxglove_port(bridge)
        assert _listening_on_loopback_only(port)
        scene = small_scene()
        bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode())
        bus.publish("DRAKE_VIEWER_DRAW", draw_of(scene, 0.0))  # the channels appear
        good = FoxgloveClient(port)
        good.subscribe("/drake/transforms")
        # Garbage: binary junk, JSON junk, an unknown channel, a subscription cut off mid-frame.
        unknown_channel = {"op": "subscribe", "subscriptions": [{"id": 9, "channelId": 999}]}
        for junk in (b"\xff" * 100, "not json", json.dumps(unknown_channel), json.dumps({"op": "explode"})):
            bad = FoxgloveClient(port)
            bad.pump(0.2)
            bad.ws.send(junk)
            bad.pump(0.2)
            bad.close()
        raw = socket.create_connection(("127.0.0.1", port))
        raw.sendall(b"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                    b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                    b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n\x82\x7e\x10\x00ab")  # fmt: skip
        raw.close()  # gone in the middle of a frame that claimed 4096 bytes
        for index in range(25):
            bus.publish("DRAKE_VIEWER_DRAW", draw_of(scene, index / 10))
            time.sleep(0.02)
        assert good.pump(5, lambda: len(good.messages.get("/drake/transforms", [])) >= 20)  # type: ignore[union-attr]
        assert bridge.process.poll() is None
    finally:
        if good is not None:
            good.close()
        assert bridge.stop() == 0
        bus.close()


def _listening_on_loopback_only(port: int) -> bool:
    """The server's listening socket, from /proc/net/tcp: bound to 127.0.0.1, not 0.0.0.0."""
    addresses = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        address, hex_port = local.split(":")
        if int(hex_port, 16) == port and state == "0A":  # LISTEN
            addresses.add(socket.inet_ntoa(struct.pack("<I", int(address, 16))))
    return addresses == {"127.0.0.1"}



def test_convert_to_foxglove_mcap_carries_the_scene_and_the_transforms(drake_log: Path, tmp_path: Path) -> None:
    import subprocess
    import sys

    from mcap.reader import make_reader

    from bridge.transports.lcm import read_log

    out = tmp_path / "drake_foxglove.mcap"
    result = subprocess.run(
        [sys.executable, "-m", "bridge.cli", "convert", str(drake_log), str(out), "--schema", "foxglove"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    topics: dict[str, list[tuple[str, bytes, int]]] = {}
    with out.open("rb") as file:
        reader = make_reader(file)
        for schema, channel, message in reader.iter_messages():
            assert channel.message_encoding == "protobuf" and schema is not None and schema.encoding == "protobuf"
            topics.setdefault(channel.topic, []).append((schema.name, message.data, message.log_time))
    assert set(topics) == {f"/drake/{role}/{kind}" for role in ("illustration", "proximity")
                           for kind in ("scene", "transforms")}  # fmt: skip
    load = next(read_log(drake_log, "DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION"))
    check_scene(scene_of([data for _, data, _ in topics["/drake/illustration/scene"]]),
                drake_lcmtypes.lcmt_viewer_load_robot.decode(load.data))  # fmt: skip
    draws = list(read_log(drake_log, "DRAKE_VIEWER_DRAW_ILLUSTRATION"))
    transforms = topics["/drake/illustration/transforms"]
    assert len(transforms) == len(draws)  # one FrameTransforms per draw, at the log's time
    for (schema_name, data, log_time), event in zip(transforms, draws, strict=True):
        draw = drake_lcmtypes.lcmt_viewer_draw.decode(event.data)
        message = _transforms(data)
        assert schema_name == "foxglove.FrameTransforms" and log_time == event.timestamp_us * 1000
        assert _stamp_ms(message) == draw.timestamp
        rows = [[t.translation.x, t.translation.y, t.translation.z, t.rotation.w, t.rotation.x, t.rotation.y,
                 t.rotation.z] for t in message.transforms]  # fmt: skip
        assert rows == [list(p) + list(q) for p, q in zip(draw.position, draw.quaternion, strict=True)]
    proximity = _transforms(topics["/drake/proximity/transforms"][0][1])
    assert all(t.child_frame_id.startswith("proximity/") for t in proximity.transforms)
