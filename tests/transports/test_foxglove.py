"""The Foxglove transport end to end: a real pydrake simulation, the bridge as a process with
`-c builtin:foxglove`, and two clients: one written here from the Foxglove WebSocket protocol
(JSON control messages; binary message data `0x01 | u32 subscription id | u64 time | payload`),
which the server answers with `foxglove.sdk.v1`, and Foxglove's own `@foxglove/ws-protocol`
client under Node.js (tests/node/foxglove_client.js), which asks for `foxglove.websocket.v1`.
Payloads are decoded with foxglove-schemas-protobuf."""

from __future__ import annotations

import base64
import contextlib
import json
import re
import resource
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import drake as drake_lcmtypes
import pytest
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect
from websockets.typing import Origin, Subprotocol

from tests.conftest import CHILDREN, lcm_url, publish_until
from tests.formats import oracle
from tests.peers import BridgeProcess
from tests.sdk_race import making_channels
from tests.test_router import LcmRecorder, start_drake

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
NODE_CLIENT = Path(__file__).parents[1] / "node" / "foxglove_client.js"  # ./dev installs its packages


class FoxgloveClient:
    """A minimal Foxglove WebSocket client: reads advertisements, subscribes, keeps payloads."""

    def __init__(self, port: int) -> None:
        # It reads only while a test pumps it: a test waiting meanwhile (on Drake, on a loaded
        # machine, for tens of seconds) must not lose it. websockets' defaults would: past 16
        # frames unread it stops reading the socket (max_queue), so the answer to its keepalive
        # ping sent every 20 s is never read, and 20 s later it closes the connection (1011).
        self._connection = connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS,  # type: ignore[arg-type]
                                   ping_interval=None, max_queue=None)  # fmt: skip
        self.ws: ClientConnection = self._connection.__enter__()
        self.subprotocol: str | None = self.ws.subprotocol
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
                elif message["op"] == "unadvertise":
                    gone = set(message["channelIds"])
                    self.channels = {topic: c for topic, c in self.channels.items() if c["id"] not in gone}
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

    def log(self) -> str:
        """What it saw, for a failed wait: the channels advertised, the payloads per topic."""
        return f"advertised {sorted(self.channels)}, received {_counts(self.messages)}"

    def close(self) -> None:
        self._connection.__exit__(None, None, None)


class WsProtocolClient:
    """Foxglove's `@foxglove/ws-protocol` FoxgloveClient in a Node.js process, subscribed to
    `topics` as they are advertised; it prints what it receives as JSON lines. With `resubscribe`
    False it never subscribes again after the server refused a subscription."""

    def __init__(self, port: int, *topics: str, resubscribe: bool = True) -> None:
        once = [] if resubscribe else ["--no-resubscribe"]
        command = ["node", str(NODE_CLIENT), *once, f"ws://127.0.0.1:{port}", *topics]
        # A process group of its own, in this session: the kernel schedules a session as one group
        # (autogroup), and tests/sdk_race.py needs the client weighed as this process's threads are.
        self.process = subprocess.Popen(
            command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, process_group=0
        )
        CHILDREN.add(self.process)  # ended with the test all the same
        self.subprotocol: str | None = None
        self.events: list[dict[str, Any]] = []  # every line, errors included (shown when a wait fails)
        self.channels: dict[str, dict[str, Any]] = {}  # topic -> advertised channel
        self.messages: dict[str, list[bytes]] = {}  # topic -> payloads, in arrival order
        self._arrived = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            event = json.loads(line)
            with self._arrived:
                self.events.append(event)
                if event["event"] == "open":
                    self.subprotocol = event["subprotocol"]
                elif event["event"] == "advertise":
                    self.channels[event["topic"]] = event
                elif event["event"] == "message":
                    self.messages.setdefault(event["topic"], []).append(base64.b64decode(event["data"]))
                self._arrived.notify_all()

    def pump(self, seconds: float, until: Callable[[], bool]) -> bool:
        with self._arrived:
            return self._arrived.wait_for(until, timeout=seconds)

    def send(self, **command: Any) -> None:
        """A command to the client (foxglove_client.js: advertise a client channel, publish on it)."""
        assert self.process.stdin is not None
        self.process.stdin.write(json.dumps(command) + "\n")
        self.process.stdin.flush()

    def seen(self, kind: str) -> list[dict[str, Any]]:
        """The events of one kind so far ("status", "serverInfo", "advertised" ...)."""
        with self._arrived:
            return [event for event in self.events if event["event"] == kind]

    def log(self) -> str:
        """What it saw, for a failed wait: every event but the messages, then the payloads per topic."""
        events = [event for event in self.events if event["event"] != "message"]
        return f"events {events}, received {_counts(self.messages)}"

    def close(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()  # the client closes its WebSocket and exits
        assert self.process.wait(timeout=30) == 0
        self._reader.join(timeout=5)
        errors = [event for event in self.events if event["event"] == "error"]
        assert not errors, errors


def _counts(messages: dict[str, list[bytes]]) -> dict[str, int]:
    return {topic: len(payloads) for topic, payloads in messages.items()}


class Client(Protocol):
    subprotocol: str | None
    channels: dict[str, dict[str, Any]]  # topic -> advertised channel (encoding, schemaName, schema ...)
    messages: dict[str, list[bytes]]

    def pump(self, seconds: float, until: Callable[[], bool]) -> bool: ...

    def log(self) -> str: ...

    def close(self) -> None: ...


def python_client(port: int, *topics: str) -> Client:
    client = FoxgloveClient(port)
    client.subscribe(*topics)
    return client


# Each client, and the subprotocol the server must have chosen for it.
CLIENTS: dict[str, tuple[Callable[..., Client], str]] = {
    "python": (python_client, "foxglove.sdk.v1"),  # offers both names
    "ws-protocol": (WsProtocolClient, "foxglove.websocket.v1"),  # offers the older name only
}


def foxglove_port(bridge: BridgeProcess) -> int:
    line = bridge.wait_for_line(" running (")
    match = re.search(r"ws://127\.0\.0\.1:(\d+)", line)
    assert match is not None, line
    # The SDK's own start-up line would name the port behind the front: not shown.
    assert not [line for line in bridge.lines if "Started server on" in line], bridge.lines
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
        kind = {1: "cubes", 2: "spheres", 3: "cylinders", 4: "models", 5: "cylinders", 6: "spheres"}[
            geometry.type
        ]
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


DRAW_CHANNEL = "DRAKE_VIEWER_DRAW_ILLUSTRATION"


@pytest.mark.parametrize("client_kind", list(CLIENTS))
def test_a_drake_simulation_reaches_a_foxglove_client(client_kind: str, tmp_path: Path) -> None:
    connect_client, subprotocol = CLIENTS[client_kind]
    url = lcm_url(12)
    recorder = LcmRecorder(url)
    # time: sim: the transforms are stamped with the draw's sim time, which tells the last draw.
    bridge = BridgeProcess(
        "-c", "builtin:foxglove", "--lcm-url", url, "--stats-period", "1", "--set", "time=sim"
    )
    client = late = None
    try:
        port = foxglove_port(bridge)
        drake = start_drake(url, tmp_path, 3.0)
        # A channel is advertised with its stream's first message; the lazy routes translate
        # once this client subscribes, the load they skipped first.
        client = connect_client(port, "/drake/illustration/scene", "/drake/illustration/transforms")
        assert drake.wait(timeout=120) == 0
        recorder.sync()  # holds Drake's last draw
        draws = recorder.messages[DRAW_CHANNEL]
        last = drake_lcmtypes.lcmt_viewer_draw.decode(draws[-1])

        def has_last_draw() -> bool:
            payloads = client.messages.get("/drake/illustration/transforms", [])  # type: ignore[union-attr]
            return bool(payloads) and _stamp_ms(_transforms(payloads[-1])) == last.timestamp

        if not client.pump(60, has_last_draw):
            # Drake sent its last draw once, over UDP: on a loaded machine the datagram can be lost
            # before the bridge reads it (counted as the LCM transport's dropped_by_kernel). The
            # same bytes again, until the client has them.
            try:
                publish_until(url, draws[-1], lambda: client.pump(0.5, has_last_draw), 60, DRAW_CHANNEL)
            except AssertionError:  # said with what the client and the bridge saw, not the bytes sent
                raise AssertionError(f"the last draw (at {last.timestamp} ms) never reached the client: "
                                     f"{client.log()}; the bridge: {bridge.lines[-10:]}") from None  # fmt: skip
        assert client.pump(60, lambda: bool(client.messages.get("/drake/illustration/scene"))), client.log()  # type: ignore[union-attr]
        assert client.subprotocol == subprotocol
        # A client that connects after the load still receives the whole scene.
        late = connect_client(port, "/drake/illustration/scene")
        assert late.pump(60, lambda: bool(late.messages.get("/drake/illustration/scene"))), late.log()  # type: ignore[union-attr]
    finally:
        for each in (client, late):
            if each is not None:
                each.close()
        assert bridge.stop() == 0
        recorder.close()
    load = drake_lcmtypes.lcmt_viewer_load_robot.decode(
        recorder.messages["DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION"][0]
    )
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
    from viewer_bridge.examples.scenes import draw_of, small_scene
    from viewer_bridge.formats.drake.load import load_from_scene
    from viewer_bridge.transports.lcm import LcmBus

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
        assert good.pump(60, lambda: len(good.messages.get("/drake/transforms", [])) >= 20)  # type: ignore[union-attr]
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


def test_convert_to_foxglove_mcap_carries_the_scene_and_the_transforms(
    drake_log: Path, tmp_path: Path
) -> None:
    import subprocess

    from mcap.reader import make_reader

    from viewer_bridge.transports.lcm import read_log

    out = tmp_path / "drake_foxglove.mcap"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "viewer_bridge.cli.main",
            "convert",
            str(drake_log),
            str(out),
            "--schema",
            "foxglove",
        ],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    topics: dict[str, list[tuple[str, bytes, int]]] = {}
    with out.open("rb") as file:
        reader = make_reader(file)
        for schema, channel, message in reader.iter_messages():
            assert (
                channel.message_encoding == "protobuf"
                and schema is not None
                and schema.encoding == "protobuf"
            )
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
        stamp = message.transforms[0].timestamp  # the log's receive time too, as /tf (time: receive)
        assert stamp.seconds * 1_000_000 + stamp.nanos // 1000 == event.timestamp_us
        rows = [[t.translation.x, t.translation.y, t.translation.z, t.rotation.w, t.rotation.x, t.rotation.y,
                 t.rotation.z] for t in message.transforms]  # fmt: skip
        assert rows == [list(p) + list(q) for p, q in zip(draw.position, draw.quaternion, strict=True)]
    proximity = _transforms(topics["/drake/proximity/transforms"][0][1])
    assert all(t.child_frame_id.startswith("proximity/") for t in proximity.transforms)


# --- The front: both subprotocol names on one port ------------------------------------------------


def test_the_front_serves_each_name_what_it_asked_for() -> None:
    from websockets.exceptions import InvalidStatus

    from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport

    transport = FoxgloveTransport(FoxgloveSettings(port=0))
    url = f"ws://127.0.0.1:{transport.port}"
    closed = False
    try:
        for offered, chosen in [
            (["foxglove.websocket.v1"], "foxglove.websocket.v1"),
            (["foxglove.sdk.v1"], "foxglove.sdk.v1"),
            (["foxglove.websocket.v1", "foxglove.sdk.v1"], "foxglove.sdk.v1"),
        ]:
            with connect(url, subprotocols=offered, open_timeout=60) as ws:  # type: ignore[arg-type]
                assert ws.subprotocol == chosen
                info = json.loads(ws.recv(timeout=60))
                assert info["op"] == "serverInfo" and info["name"] == "viewer-bridge"
        with pytest.raises(InvalidStatus, match="400"):  # a name neither of them: the SDK refuses it
            connect(url, subprotocols=["foxglove.websocket.v2"], open_timeout=60)  # type: ignore[list-item]
        # A request cut off before its end is dropped and counted; the front goes on serving.
        with socket.create_connection(("127.0.0.1", transport.port)) as raw:
            raw.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")
        deadline = time.monotonic() + 60
        while transport.errors().get("bad_handshake") != 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert transport.errors() == {"bad_handshake": 1}
        with connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=60) as ws:  # type: ignore[list-item]
            ws.recv(timeout=60)
            transport.close()
            closed = True
            with pytest.raises(ConnectionClosed):  # closing the transport ends its clients' connections
                ws.recv(timeout=60)
    finally:
        if not closed:
            transport.close()


def test_a_client_that_subscribes_before_its_channel_is_stored_is_counted(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The SDK advertises a channel the moment it is made, so a connected client may subscribe
    before `publisher` has stored it: that subscriber must still be counted, or a lazy route
    publishing there never wakes for it (one of two /lcm channels missed for good, under load).
    The delay is injected: the client subscribes, and the SDK reports it, between the two."""
    from viewer_bridge.transports import foxglove as module
    from viewer_bridge.transports.base import PROTOBUF, MessageType, Qos

    reported = threading.Event()
    on_subscribe = module._Listener.on_subscribe

    def reporting(listener: Any, client: Any, channel: Any) -> None:
        on_subscribe(listener, client, channel)
        reported.set()

    monkeypatch.setattr(module._Listener, "on_subscribe", reporting)
    transport = module.FoxgloveTransport(module.FoxgloveSettings(port=0))
    client = FoxgloveClient(transport.port)
    make_channel = module.FoxgloveContext.channel

    def subscribed_as_made(context: Any, topic: str, message_type: MessageType, name: str) -> Any:
        made = make_channel(context, topic, message_type, name)
        client.subscribe(topic)  # waits for the advertisement, then subscribes
        assert reported.wait(60), f"the SDK never reported the subscription to {topic}: {client.log()}"
        return made

    monkeypatch.setattr(module.FoxgloveContext, "channel", subscribed_as_made)
    try:
        publisher = transport.publisher("/t", MessageType("foxglove.FrameTransforms", PROTOBUF), Qos())
        assert publisher.subscriber_count() == 1
        publisher.publish(FrameTransforms().SerializeToString())
        assert client.pump(60, lambda: "/t" in client.messages), client.log()
        client.close()
        client = None
        deadline = time.monotonic() + 60  # the SDK reports the client gone on its own thread
        while publisher.subscriber_count() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert publisher.subscriber_count() == 0
    finally:
        if client is not None:
            client.close()
        transport.close()


def test_a_client_that_never_subscribes_again_gets_every_topic_advertised_during_the_sdks_race() -> None:
    """Foxglove's ws-protocol client, told not to subscribe again by itself, subscribes to each
    topic the moment it is advertised, while the transport makes the topics on a thread the SDK's
    subscribe race catches (tests/sdk_race.py): every topic's message reaches it, since the front
    sends each subscription the SDK refused again. Without that repair this fails."""
    from viewer_bridge.transports.base import PROTOBUF, MessageType, Publisher, Qos
    from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport

    transport = FoxgloveTransport(FoxgloveSettings(port=0))
    topics = [f"/race/{index}" for index in range(30)]
    client = WsProtocolClient(transport.port, *topics, resubscribe=False)
    publishers: list[Publisher] = []

    def make() -> None:
        for topic in topics:
            publishers.append(
                transport.publisher(topic, MessageType("foxglove.FrameTransforms", PROTOBUF), Qos())
            )
            time.sleep(0.02)

    try:
        assert client.pump(60, lambda: bool(client.seen("serverInfo"))), client.log()
        with making_channels(make, peers=[client.process.pid]):
            pass
        assert len(publishers) == len(topics)
        deadline = time.monotonic() + 60
        while not all(each.subscriber_count() for each in publishers) and time.monotonic() < deadline:
            time.sleep(0.05)
        for publisher in publishers:
            publisher.publish(FrameTransforms().SerializeToString())
        assert client.pump(60, lambda: set(client.messages) == set(topics)), (
            sorted(set(topics) - set(client.messages)),
            client.seen("status"),
        )
        assert not [status for status in client.seen("status") if "Unknown channel" in status["message"]]
        assert transport.errors().get("resubscribed", 0) >= 1, transport.errors()  # the race did happen
    finally:
        client.close()
        transport.close()


def test_a_closed_publisher_takes_its_channel_away_and_the_transport_forgets_it() -> None:
    """A route lets a quiet stream go (`stream_idle_s`) by closing its publisher: clients see the
    channel unadvertised, and the transport keeps nothing of it, so a flood of names that comes and
    goes cannot grow it; the topic may be published again later."""
    from viewer_bridge.transports.base import PROTOBUF, Closable, MessageType, Qos
    from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport

    transport = FoxgloveTransport(FoxgloveSettings(port=0))
    client = FoxgloveClient(transport.port)
    transforms = MessageType("foxglove.FrameTransforms", PROTOBUF)
    try:
        publisher = transport.publisher("/lcm/JUNK", transforms, Qos())
        assert isinstance(publisher, Closable)
        assert client.pump(60, lambda: "/lcm/JUNK" in client.channels), client.log()
        publisher.close()
        assert client.pump(60, lambda: "/lcm/JUNK" not in client.channels), client.log()
        assert transport.topics() == [] and transport.context.topics() == []
        again = transport.publisher("/lcm/JUNK", transforms, Qos())
        client.subscribe("/lcm/JUNK")
        assert client.pump(60, lambda: again.subscriber_count() == 1)
        again.publish(FrameTransforms().SerializeToString())
        assert client.pump(60, lambda: "/lcm/JUNK" in client.messages), client.log()
    finally:
        client.close()
        transport.close()


def test_without_renaming_only_the_sdks_name_is_served() -> None:
    from websockets.exceptions import InvalidStatus

    from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport

    transport = FoxgloveTransport(FoxgloveSettings(port=0, accept_websocket_v1=False, client_publish=False))
    url = f"ws://127.0.0.1:{transport.port}"
    try:
        # The front holds the port all the same (it checks origins: tests/transports/test_foxglove_front.py).
        assert transport.front.port == transport.port != transport.server.port
        with connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=60) as ws:  # type: ignore[list-item]
            assert ws.subprotocol == "foxglove.sdk.v1"
        with pytest.raises(InvalidStatus, match="400"):
            connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=60)  # type: ignore[list-item]
    finally:
        transport.close()


def test_the_front_renames_the_subprotocol_header_only() -> None:
    from viewer_bridge.transports.foxglove_front import naming, older_name_asked, subprotocols

    request = (b"GET / HTTP/1.1\r\nHost: x\r\nsec-websocket-protocol: a, foxglove.websocket.v1\r\n"
               b"Sec-WebSocket-Protocol: b\r\nUpgrade: websocket\r\n\r\n")  # fmt: skip
    assert subprotocols(request) == ["a", "foxglove.websocket.v1", "b"]
    assert older_name_asked(request) == "foxglove.websocket.v1"
    renamed = naming(request, "foxglove.sdk.v1")
    assert renamed == (b"GET / HTTP/1.1\r\nSec-WebSocket-Protocol: foxglove.sdk.v1\r\nHost: x\r\n"
                       b"Upgrade: websocket\r\n\r\n")  # fmt: skip
    assert older_name_asked(renamed) is None  # the SDK's own name: nothing to rename
    refusal = b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\n\r\n"
    assert naming(refusal, "foxglove.websocket.v1") == refusal  # no header to rename


@pytest.mark.parametrize("client_kind", list(CLIENTS))
def test_any_lcm_type_from_a_pydrake_diagram_reaches_a_foxglove_client_as_ros2msg(
    client_kind: str, tmp_path: Path
) -> None:
    """Drake's driver messages (an LcmPublisherSystem each) on /lcm/<channel>: a `ros2msg` schema
    and CDR, decoded by mcap-ros2-support from the schema the client was advertised."""
    from mcap_ros2._dynamic import generate_dynamic

    from tests.drake_robot_status import PLAN_CHANNEL, STATUS_CHANNEL, drive_until
    from tests.translators.test_lcm_generic import assert_same

    connect_client, _ = CLIENTS[client_kind]
    url = lcm_url(13)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("-c", "builtin:foxglove", "--lcm-url", url, "--stats-period", "1")
    topics = {STATUS_CHANNEL: "/lcm/IIWA_STATUS", PLAN_CHANNEL: "/lcm/ROBOT_PLAN"}
    client: Client | None = None

    def arrived() -> bool:
        nonlocal client
        if client is None:  # each channel is advertised as it appears: connected once the driver publishes
            if not recorder.messages.get(STATUS_CHANNEL):
                return False
            client = connect_client(port, *topics.values())
        return client.pump(0.1, lambda: all(len(client.messages.get(t, [])) >= 10 for t in topics.values()))  # type: ignore[union-attr]

    try:
        port = foxglove_port(bridge)
        # The lazy routes wake once the client subscribes: the driver publishes until it has its share.
        assert drive_until(url, arrived), client.log() if client is not None else "never connected"
        recorder.sync()  # holds every message the driver sent
    finally:
        if client is not None:
            client.close()
        assert bridge.stop() == 0
        recorder.close()
    assert client is not None
    for channel, lcm_class in ((STATUS_CHANNEL, drake_lcmtypes.lcmt_iiwa_status),
                               (PLAN_CHANNEL, drake_lcmtypes.lcmt_robot_plan)):  # fmt: skip
        advertised = client.channels[topics[channel]]
        name = f"drake_lcm_msgs/msg/{'LcmtIiwaStatus' if channel == STATUS_CHANNEL else 'LcmtRobotPlan'}"
        assert (advertised["encoding"], advertised["schemaName"], advertised["schemaEncoding"]) == (
            "cdr", name, "ros2msg")  # fmt: skip
        decode = generate_dynamic(name, advertised["schema"])[name]
        sent = {lcm_class.decode(data).utime: lcm_class.decode(data) for data in recorder.messages[channel]}
        for payload in client.messages[topics[channel]]:
            message = decode(payload)
            assert_same(sent[message.utime], message)


# --- Hostile clients at the door (issue 51, rows 1 and 13) ------------------------------------------------

STALLED = 1100  # connections of the attack: more than the bridge's 1024 files
EVIL = "https://evil.example"
SDK_NAME = Subprotocol("foxglove.sdk.v1")


def served(port: int) -> bool:
    """Whether a plain client gets its serverInfo from the Foxglove server at `port`."""
    with connect(
        f"ws://127.0.0.1:{port}", subprotocols=[SDK_NAME], open_timeout=60, ping_interval=None
    ) as ws:
        return bool(json.loads(ws.recv(timeout=60))["op"] == "serverInfo")


def _stalling(port: int) -> socket.socket:
    """A connection to `port` that sends nothing yet (connecting without waiting: a door that
    stopped accepting must not hang the test)."""
    sock = socket.socket()
    sock.setblocking(False)
    sock.connect_ex(("127.0.0.1", port))
    return sock


def _trickle(
    port: int, stalled: list[socket.socket], stop: threading.Event, rounds: threading.Semaphore
) -> None:
    """Every 2 s, one more byte of a request head on each connection; one the bridge closed is
    made again, as an attacker would."""
    head = b"GET / HTTP/1.1\r\nHost: x\r\n"
    sent = 0
    while not stop.is_set():
        for index, sock in enumerate(stalled):
            try:
                sock.send(head[sent % len(head) : sent % len(head) + 1])
            except (BlockingIOError, InterruptedError):
                pass  # still connecting, or its buffer is full
            except OSError:  # closed by the bridge: again
                sock.close()
                stalled[index] = _stalling(port)
        sent += 1
        rounds.release()
        stop.wait(2.0)


def _files_here(count: int) -> None:
    """This test process needs `count` files: raise its soft limit if it is lower."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < count:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(count, hard), hard))


def test_a_crowd_of_stalled_handshakes_under_a_1024_file_limit_leaves_the_bridge_serving() -> None:
    """1,100 connections, each sending one header byte now and then, to a bridge whose open-file
    limit is 1024 (the common default): the bridge stays up (its stats report every 0.5 s runs
    throughout), a plain client is served while they stall and after they are gone, and the
    dropped connections are a few log lines, not one each."""
    _files_here(STALLED + 500)
    bridge = BridgeProcess("-c", "builtin:foxglove", "--lcm-url", lcm_url(16), "--stats-period", "0.5",
                           max_files=1024)  # fmt: skip
    stop, rounds = threading.Event(), threading.Semaphore(0)
    stalled: list[socket.socket] = []
    try:
        port = foxglove_port(bridge)
        stalled.extend(_stalling(port) for _ in range(STALLED))
        trickler = threading.Thread(target=_trickle, args=(port, stalled, stop, rounds), daemon=True)
        trickler.start()
        for _ in range(3):  # the attack under way: its connections made, two bytes each so far
            assert rounds.acquire(timeout=60)
        assert served(port), "\n".join(bridge.lines[-40:])
        for _ in range(6):  # past the handshake deadline: the first of them are dropped and made again
            assert rounds.acquire(timeout=60)
        assert served(port) and bridge.process.poll() is None
        stop.set()
        trickler.join(timeout=60)
        for sock in stalled:
            sock.close()
        assert served(port)
        assert bridge.process.poll() is None, "\n".join(bridge.lines)
        dropped = [line for line in bridge.lines if "foxglove client connection dropped" in line
                   or "request under way dropped" in line]  # fmt: skip
        assert 0 < len(dropped) < 20, "\n".join(dropped[:40])
    finally:
        stop.set()
        for sock in stalled:
            sock.close()
        assert bridge.stop() == 0, "\n".join(bridge.lines[-40:])


def test_a_page_that_finds_the_sdks_own_port_reads_nothing_there() -> None:
    """The SDK's server behind the front, found by a scan of loopback ports: a WebSocket request
    from a foreign page gets no HTTP answer (the SDK speaks TLS only), `wss://` is refused for
    its certificate (no authority signed it), and the front still serves the same page's
    request with 403 and a program's with the stream."""
    import ssl

    from websockets.exceptions import InvalidStatus

    from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport

    transport = FoxgloveTransport(FoxgloveSettings(port=0))
    try:
        sdk_port = transport.server.port
        request = (b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                   b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                   b"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\nOrigin: https://evil.example\r\n\r\n")  # fmt: skip
        with socket.create_connection(("127.0.0.1", sdk_port), timeout=60) as scan:
            scan.sendall(request)
            answer = b""
            with contextlib.suppress(OSError):  # reset, or closed
                while chunk := scan.recv(65536):
                    answer += chunk
        assert not answer.startswith(b"HTTP") and b"serverInfo" not in answer, answer[:200]
        with pytest.raises(ssl.SSLCertVerificationError):  # what a browser's wss:// meets
            connect(f"wss://127.0.0.1:{sdk_port}", origin=Origin(EVIL), subprotocols=[SDK_NAME],
                    open_timeout=60).close()  # fmt: skip
        with pytest.raises(InvalidStatus):  # and at the front: 403
            connect(f"ws://127.0.0.1:{transport.port}", origin=Origin(EVIL), subprotocols=[SDK_NAME],
                    open_timeout=60).close()  # fmt: skip
        assert served(transport.port)
    finally:
        transport.close()
