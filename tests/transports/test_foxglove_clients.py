"""Foxglove clients that publish: Foxglove's own `@foxglove/ws-protocol` client under Node.js
(tests/node/foxglove_client.js) advertises client channels and publishes on them; the bridge takes
`lcmt_iiwa_command` as JSON and as CDR (made here by rosbags from the type's `.msg`) to LCM, where
pydrake's lcm-gen'd class decodes it, and says what it refuses to the client that sent it alone."""

from __future__ import annotations

import base64
import json
import logging
import time
from collections.abc import Iterator
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest

from tests.conftest import lcm_url
from tests.peers import BridgeProcess
from tests.test_router import LcmRecorder
from tests.transports.test_foxglove import WsProtocolClient, foxglove_port
from viewer_bridge.errors import DecodeError
from viewer_bridge.transports.base import CDR, JSON, MessageType, Qos, Received
from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport
from viewer_bridge.transports.foxglove_front import Connection

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
COMMAND_TYPE = "drake_lcm_msgs/msg/LcmtIiwaCommand"
WAIT = 60.0
# Every channel these tests command, and an age limit no loaded machine reaches (freshness has its
# own tests: tests/router/test_commands.py).
COMMANDS_ALLOWED = ("--allow-commands", ".*", "--set", "commands.max_age_ms=60000")


def connected(port: int) -> WsProtocolClient:
    """A ws-protocol client that has its serverInfo (so it may publish)."""
    client = WsProtocolClient(port)
    assert client.pump(WAIT, lambda: bool(client.seen("serverInfo"))), client.log()
    return client


def statuses(client: WsProtocolClient) -> list[str]:
    return [event["message"] for event in client.seen("status") if event["level"] == 2]


def wait_for_status(client: WsProtocolClient, *words: str) -> str:
    """The first error status naming all of `words` (waited for)."""

    def found() -> str | None:
        return next((text for text in statuses(client) if all(word in text for word in words)), None)

    assert client.pump(WAIT, lambda: found() is not None), client.log()
    text = found()
    assert text is not None
    return text


# --- The transport alone: what reaches a route, what is said to whom ------------------------------------


@pytest.fixture
def transport() -> Iterator[FoxgloveTransport]:
    made = FoxgloveTransport(FoxgloveSettings(port=0))
    yield made
    made.close()


def test_a_clients_messages_reach_the_routes_of_their_topic_with_their_type_and_sender(
    transport: FoxgloveTransport,
) -> None:
    delivered: list[Received] = []
    transport.subscribe("/lcm_in/(.*)", MessageType("*", CDR), Qos(), delivered.append)
    publisher, bystander = connected(transport.port), connected(transport.port)
    try:
        (info,) = publisher.seen("serverInfo")
        assert "clientPublish" in info["capabilities"] and info["supportedEncodings"] == ["cdr", "json"]
        # pkg/Name (as Foxglove's panels may say a ROS type) is pkg/msg/Name.
        publisher.send(op="advertise", topic="/lcm_in/IIWA_COMMAND", encoding="json",
                       schemaName="drake_lcm_msgs/LcmtIiwaCommand")  # fmt: skip
        publisher.send(op="publish", name="/lcm_in/IIWA_COMMAND", data=_b64(b'{"utime": 7}'))
        deadline = time.monotonic() + WAIT
        while not delivered and time.monotonic() < deadline:
            time.sleep(0.02)
        (received,) = delivered
        assert (received.channel, received.data) == ("/lcm_in/IIWA_COMMAND", b'{"utime": 7}')
        assert received.message_type == MessageType(COMMAND_TYPE, JSON)
        assert isinstance(received.origin, Connection)

        # A route refused it: the error status names the topic and the field, at that client alone.
        transport.rejected(
            received, DecodeError("drake.lcmt_iiwa_command", "joint_position", 0, "not an array")
        )
        text = wait_for_status(publisher, "/lcm_in/IIWA_COMMAND", "joint_position")
        assert "not an array" in text and COMMAND_TYPE in text

        # A topic no route reads and an encoding the bridge does not read: said on advertise.
        publisher.send(
            op="advertise", topic="/cmd_vel", encoding="json", schemaName="geometry_msgs/msg/Twist"
        )
        publisher.send(op="advertise", topic="/lcm_in/X", encoding="protobuf", schemaName="foxglove.Pose")
        assert "no route" in wait_for_status(publisher, "/cmd_vel")
        assert "encoding 'protobuf'" in wait_for_status(publisher, "/lcm_in/X")
        publisher.send(op="publish", name="/cmd_vel", data=_b64(b"{}"))
        publisher.send(op="publish", name="/lcm_in/X", data=_b64(b"\x08\x01"))
        deadline = time.monotonic() + WAIT
        while transport.errors().get("client_message_dropped", 0) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert transport.errors() == {"client_channel_refused": 2, "client_message_dropped": 2}
        assert len(delivered) == 1
        # The other client, connected all along, heard none of it.
        assert not statuses(bystander), bystander.log()
    finally:
        publisher.close()
        bystander.close()


def test_a_read_only_server_lists_no_client_publishing() -> None:
    transport = FoxgloveTransport(FoxgloveSettings(port=0, client_publish=False))
    # idle, said once
    transport.subscribe("/lcm_in/(.*)", MessageType("*", CDR), Qos(), lambda received: None)
    client = None
    try:
        client = connected(transport.port)
        (info,) = client.seen("serverInfo")
        assert "clientPublish" not in info["capabilities"] and not info["supportedEncodings"], info
    finally:
        if client is not None:
            client.close()
        transport.close()


# --- The bridge: a Foxglove client commands an LCM robot -----------------------------------------------


def command_values(utime: int) -> dict[str, Any]:
    return {"utime": utime, "num_joints": 7, "joint_position": [0.1 * (joint + utime) for joint in range(7)],
            "num_torques": 2, "joint_torque": [1.5, -2.5]}  # fmt: skip


def command_cdr(values: dict[str, Any]) -> bytes:
    """CDR of drake_lcm_msgs/msg/LcmtIiwaCommand, written by rosbags from the type's `.msg` (not ours)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from viewer_bridge.lcmcodec.library import TypeLibrary

    lcm_type = TypeLibrary.load().get("drake.lcmt_iiwa_command")
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(lcm_type.msg_definition, COMMAND_TYPE))
    fields = {key: np.array(value, dtype=np.float64) if isinstance(value, list) else value
              for key, value in values.items()}  # fmt: skip
    return bytes(store.serialize_cdr(store.types[COMMAND_TYPE](**fields), COMMAND_TYPE))


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode()


def test_a_foxglove_client_commands_an_lcm_robot_as_json_and_as_cdr() -> None:
    url = lcm_url(14)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess(
        "-c", "builtin:foxglove", "--lcm-url", url, "--stats-period", "1", *COMMANDS_ALLOWED
    )
    publisher = bystander = other = None
    try:
        port = foxglove_port(bridge)
        publisher, bystander, other = connected(port), connected(port), connected(port)
        topic = "/lcm_in/IIWA_COMMAND"
        publisher.send(op="advertise", name="json", topic=topic, encoding="json", schemaName=COMMAND_TYPE)
        publisher.send(op="advertise", name="cdr", topic=topic, encoding="cdr", schemaName=COMMAND_TYPE)
        assert publisher.pump(WAIT, lambda: len(publisher.seen("advertised")) == 2), publisher.log()  # type: ignore[union-attr]

        def commands() -> list[Any]:
            return [
                drake_lcmtypes.lcmt_iiwa_command.decode(data)
                for data in recorder.messages.get("IIWA_COMMAND", [])
            ]

        def landed(count: int) -> None:
            deadline = time.monotonic() + WAIT
            while len(commands()) < count and time.monotonic() < deadline:
                time.sleep(0.05)
            assert len(commands()) == count, bridge.lines

        # One at a time, each waited for: the route keeps the newest command per channel, so
        # commands sent faster than it takes them would be superseded (counted), by design.
        sent = [command_values(1), command_values(2)]
        publisher.send(op="publish", name="json", data=_b64(json.dumps(sent[0]).encode()))
        landed(1)
        publisher.send(op="publish", name="cdr", data=_b64(command_cdr(sent[1])))
        landed(2)
        # Malformed: a wrong type in JSON; CDR whose length field says 7 joints for 6 positions.
        # Each: an error status at its client naming the field (and the length field).
        wrong_type = command_values(3) | {"joint_position": "seven numbers"}
        publisher.send(op="publish", name="json", data=_b64(json.dumps(wrong_type).encode()))
        wait_for_status(publisher, topic, f"{COMMAND_TYPE} (json)", "joint_position", "string")
        short = command_values(4)
        short["joint_position"] = short["joint_position"][:6]
        publisher.send(op="publish", name="cdr", data=_b64(command_cdr(short)))
        wait_for_status(publisher, topic, f"{COMMAND_TYPE} (cdr)", "joint_position", "num_joints")
        sent.append(command_values(5))  # and the next good one flows
        publisher.send(op="publish", name="json", data=_b64(json.dumps(sent[2]).encode()))
        landed(3)
        recorder.sync()
        received = commands()
        assert [command.utime for command in received] == [1, 2, 5], bridge.lines
        for command, values in zip(received, sent, strict=True):
            assert command.num_joints == 7 and command.num_torques == 2
            assert list(command.joint_position) == values["joint_position"]
            assert list(command.joint_torque) == values["joint_torque"]

        # Another schema (the Teleop panel's Twist) on /lcm_in/: said to that client too.
        other.send(
            op="advertise", topic="/lcm_in/CMD_VEL", encoding="json", schemaName="geometry_msgs/msg/Twist"
        )
        other.send(op="publish", name="/lcm_in/CMD_VEL", data=_b64(b'{"linear": {"x": 1.0}}'))
        assert "geometry_msgs/msg/Twist" in wait_for_status(other, "/lcm_in/CMD_VEL")
        recorder.sync()
        assert "CMD_VEL" not in recorder.messages
        # The client that only listened heard none of it.
        assert not statuses(bystander), bystander.log()
        assert not [text for text in statuses(publisher) if "CMD_VEL" in text]
    finally:
        for client in (publisher, bystander, other):
            if client is not None:
                client.close()
        assert bridge.stop() == 0
        recorder.close()


def test_one_setting_makes_the_bridge_read_only() -> None:
    bridge = BridgeProcess(
        "-c", "builtin:foxglove", "--lcm-url", lcm_url(14), "--set", "foxglove.client_publish=false"
    )
    client = None
    try:
        client = connected(foxglove_port(bridge))
        (info,) = client.seen("serverInfo")
        assert "clientPublish" not in info["capabilities"], info
        # The route that reads from clients is idle, and the log says why, once.
        bridge.wait_for_line("foxglove.client_publish is false: the route reading '/lcm_in/(.*)'")
    finally:
        if client is not None:
            client.close()
        assert bridge.stop() == 0


def test_statuses_go_between_the_sdks_messages_while_it_streams(transport: FoxgloveTransport) -> None:
    """A client that receives 100 kB messages back to back while statuses are put into its stream:
    `websockets`' strict parser reads every message whole and every status."""
    import threading

    from websockets.sync.client import connect

    from viewer_bridge.transports.base import PROTOBUF

    delivered: list[Received] = []
    transport.subscribe("/in", MessageType("*", CDR), Qos(), delivered.append)
    publisher = transport.publisher("/big", MessageType("foxglove.FrameTransforms", PROTOBUF), Qos())
    payloads = [bytes([index]) * 100_000 for index in range(100)]  # within the SDK's backlog per client
    statuses_sent = 50
    with connect(
        f"ws://127.0.0.1:{transport.port}", subprotocols=["foxglove.websocket.v1"], max_size=None
    ) as ws:  # type: ignore[list-item]
        channel = None
        while channel is None:
            message = json.loads(ws.recv(timeout=WAIT))
            if message["op"] == "advertise":
                channel = message["channels"][0]["id"]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel}]}))
        advertised = {"id": 1, "topic": "/in", "encoding": "cdr", "schemaName": "a/msg/B"}
        ws.send(json.dumps({"op": "advertise", "channels": [advertised]}))
        ws.send(bytes([1, 1, 0, 0, 0]) + b"\x00\x01\x00\x00")
        deadline = time.monotonic() + WAIT
        while (not delivered or publisher.subscriber_count() != 1) and time.monotonic() < deadline:
            time.sleep(0.01)
        (received,) = delivered

        streaming = threading.Event()

        def refuse() -> None:  # while the SDK's messages stream, a status every millisecond
            streaming.wait(WAIT)
            for index in range(statuses_sent):
                transport.rejected(received, DecodeError("a.B", f"field_{index}", index, "refused"))
                time.sleep(0.001)

        refusing = threading.Thread(target=refuse)
        refusing.start()
        for payload in payloads:
            publisher.publish(payload)
        data: list[bytes] = []
        said: list[str] = []
        while len(data) < len(payloads) or len(said) < statuses_sent:
            frame = ws.recv(timeout=WAIT)
            if isinstance(frame, bytes):
                data.append(frame[13:])  # 0x01 | u32 subscription | u64 time | payload
                streaming.set()
                time.sleep(0.001)  # a client slower than the server: the stream stays busy
            elif (message := json.loads(frame))["op"] == "status":
                said.append(message["message"])
        refusing.join()
    assert data == payloads
    assert sorted(said) == sorted(f"viewer-bridge: /in (a/msg/B (cdr)): refused: a.B.field_{index} at byte {index}: refused"
                                  for index in range(statuses_sent))  # fmt: skip


def test_with_client_publishing_the_front_stays_on_the_port_but_renames_only_if_asked() -> None:
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    transport = FoxgloveTransport(FoxgloveSettings(port=0, accept_websocket_v1=False))
    url = f"ws://127.0.0.1:{transport.port}"
    try:
        assert transport.front is not None  # it answers each client alone
        with connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=WAIT) as ws:  # type: ignore[list-item]
            assert "clientPublish" in json.loads(ws.recv(timeout=WAIT))["capabilities"]
        with pytest.raises(InvalidStatus, match="400"):
            connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=WAIT)  # type: ignore[list-item]
    finally:
        transport.close()


def test_a_ros_type_as_foxglove_may_name_it() -> None:
    from viewer_bridge.transports.foxglove_clients import ros_type_name

    assert ros_type_name("drake_lcm_msgs/LcmtIiwaCommand") == COMMAND_TYPE
    assert ros_type_name(COMMAND_TYPE) == COMMAND_TYPE
    for other in ("foxglove.Pose", "", "a/", "/b"):
        assert ros_type_name(other) == other


def test_json_nested_too_deep_is_refused_as_a_bad_message_logged_once_per_client(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """50,000 nested arrays: refused as any unread message (counted, said to that client), one
    log line per client however many it sends, never a traceback."""
    from tests.fuzz.targets import RecordingConnection
    from viewer_bridge.transports.foxglove_clients import ClientPublishing
    from viewer_bridge.transports.websocket_frames import TEXT, Message

    publishing = ClientPublishing()
    deep = Message(TEXT, b'{"op": "advertise", "channels": ' + b"[" * 50_000 + b"]" * 50_000 + b"}")
    one, other = RecordingConnection(), RecordingConnection()
    with caplog.at_level(logging.DEBUG):
        for _ in range(3):
            publishing.message(one, deep)
        publishing.message(other, deep)
    assert publishing.errors() == {"client_message_unread": 4}
    assert (
        len(one.said) == 1 and "nested deeper" in json.loads(one.said[0])["message"]
    )  # then held back a while
    lines = [record for record in caplog.records if "nested deeper" in record.getMessage()]
    assert len(lines) == 2 and not any(record.exc_info for record in caplog.records)
    publishing.closed(one)
    publishing.message(one, deep)  # a client that connects again is a new one
    assert len([record for record in caplog.records if "nested deeper" in record.getMessage()]) == 3
