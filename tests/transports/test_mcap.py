"""The MCAP transport: a file of either profile read back with the mcap readers, fed offline
(`Router.feed`, as `convert` does) and live from LCM; a config that also runs the Foxglove server
shares one Foxglove context with the file."""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import lcm
import pytest
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from tests.conftest import lcm_url
from viewer_bridge.config.bridge import BridgeConfig
from viewer_bridge.errors import ConfigError, TransportUnavailable
from viewer_bridge.examples.scenes import draw_of, small_scene
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.model.scene import Scene
from viewer_bridge.router.router import Router
from viewer_bridge.transports.base import Received
from viewer_bridge.transports.foxglove import FoxgloveTransport
from viewer_bridge.transports.mcap import McapTransport

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)

LOAD = load_from_scene(small_scene()).encode()
DRAW_ROUTE = {"source": {"transport": "lcm", "name": "DRAKE_VIEWER_DRAW"}}
SCENE_ROUTE = {"source": {"transport": "lcm", "name": "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"}}


def config(mcap: dict[str, Any], *routes: dict[str, Any], **sections: Any) -> BridgeConfig:
    return BridgeConfig.model_validate(
        {"lcm": {"url": "memq://"}, "mcap": mcap, **sections, "routes": list(routes)}
    )


def route(name: str, translator: str, destination: str, topic: str, source: dict[str, Any]) -> dict[str, Any]:
    return {
        "name": name,
        **source,
        "translator": translator,
        "destination": {"transport": destination, "name": topic},
    }


def scene_and_frames(path: Path, frames_to: str, **sections: Any) -> Router:
    """The scene into a Foxglove MCAP file at `path`, the transforms to the transport `frames_to`."""
    return Router(
        config(
            {"path": path, "profile": "foxglove"},
            route("scene", "drake_to_scene_update", "mcap", "/drake/scene", SCENE_ROUTE),
            route("frames", "drake_to_frame_transforms", frames_to, "/drake/transforms", DRAW_ROUTE),
            **sections,
        )
    )


def feed(router: Router, channel: str, data: bytes, received_us: int) -> None:
    router.feed("lcm", Received(channel, data, received_us))


def read(path: Path) -> list[tuple[str, str, int, bytes]]:
    """(topic, schema name, log time, data) of every message in the file, in order."""
    with path.open("rb") as file:
        return [
            (channel.topic, schema.name if schema else "", message.log_time, message.data)
            for schema, channel, message in make_reader(file).iter_messages()
        ]


def test_a_ros2_file_holds_cdr_at_each_messages_receive_time(tmp_path: Path) -> None:
    path = tmp_path / "poses.mcap"
    router = Router(
        config({"path": path}, route("poses", "drake_to_pose_array", "mcap", "poses", DRAW_ROUTE))
    )
    scene = small_scene()
    for index in range(3):
        feed(router, "DRAKE_VIEWER_DRAW", draw_of(scene, index / 4), 1_000_000 + index)
    feed(router, "ELSEWHERE", b"", 5)  # no route reads it
    mcap = router.transports["mcap"]
    assert isinstance(mcap, McapTransport) and mcap.messages == {"/poses": 3}
    router.close()
    with path.open("rb") as file:
        reader = make_reader(file, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        messages = list(reader.iter_decoded_messages())
    assert [(channel.topic, schema.name, schema.encoding) for schema, channel, _, _ in messages] == [
        ("/poses", "geometry_msgs/msg/PoseArray", "ros2msg")  # rooted, as a node in / names it
    ] * 3
    for index, (_, _, message, decoded) in enumerate(messages):
        assert message.log_time == message.publish_time == (1_000_000 + index) * 1000
        assert [pose.position.z for pose in decoded.poses] == [index / 4] * 2


def test_a_foxglove_file_holds_the_sdks_protobuf_messages(tmp_path: Path) -> None:
    path = tmp_path / "scene.mcap"
    router = scene_and_frames(path, frames_to="mcap")
    feed(router, "DRAKE_VIEWER_LOAD_ROBOT", LOAD, 10)
    feed(router, "DRAKE_VIEWER_DRAW", draw_of(small_scene(), 0.5), 20)
    router.close()
    written = read(path)
    assert [(topic, schema, time) for topic, schema, time, _ in written] == [
        ("/drake/scene", "foxglove.SceneUpdate", 10_000),  # once per load
        ("/drake/transforms", "foxglove.FrameTransforms", 20_000),
    ]
    update = SceneUpdate.FromString(written[0][3])
    assert {entity.id for entity in update.entities} == {"plant::robot::base", "plant::robot::tip"}
    transforms = FrameTransforms.FromString(written[1][3]).transforms
    assert [transform.translation.z for transform in transforms] == [0.5, 0.5]


def test_a_live_router_records_what_arrives_on_lcm(tmp_path: Path) -> None:
    path = tmp_path / "live.mcap"
    url = lcm_url(31)
    router = Router(
        config(
            {"path": path},
            route("poses", "drake_to_pose_array", "mcap", "/poses", DRAW_ROUTE),
            lcm={"url": url},
        )
    )
    mcap = router.transports["mcap"]
    assert isinstance(mcap, McapTransport)
    router.start()
    bus = lcm.LCM(url)
    before_us = time.time_ns() // 1000
    deadline = time.monotonic() + 60
    try:
        while not mcap.messages and time.monotonic() < deadline:  # UDP may drop one: publish again
            bus.publish("DRAKE_VIEWER_DRAW", draw_of(small_scene(), 1.0))
            time.sleep(0.05)
        # Until it is closed, the file is live.mcap.partial: no file under the name is ever cut short.
        assert not path.exists() and (tmp_path / "live.mcap.partial").is_file()
    finally:
        router.close()
    after_us = time.time_ns() // 1000
    assert not (tmp_path / "live.mcap.partial").exists()
    written = read(path)
    assert written and {topic for topic, *_ in written} == {"/poses"}
    assert all(before_us * 1000 <= log_time <= after_us * 1000 for _, _, log_time, _ in written)


def test_an_mcap_file_is_no_source_and_replaces_a_file_only_when_asked(tmp_path: Path) -> None:
    reads_a_file = route(
        "poses", "drake_to_pose_array", "ros", "/poses", {"source": {"transport": "mcap", "name": "x"}}
    )
    with pytest.raises(ConfigError, match="the mcap transport only writes a file"):
        config({"path": tmp_path / "x.mcap"}, reads_a_file)
    with pytest.raises(ConfigError, match="mcap.path: Field required"):
        BridgeConfig.model_validate(
            {"routes": [route("poses", "drake_to_pose_array", "mcap", "/poses", DRAW_ROUTE)]}
        )
    existing = tmp_path / "existing.mcap"
    existing.write_bytes(b"keep")
    poses = route("poses", "drake_to_pose_array", "mcap", "/poses", DRAW_ROUTE)
    with pytest.raises(TransportUnavailable, match="exists"):
        Router(config({"path": existing}, poses))
    assert existing.read_bytes() == b"keep"
    with pytest.raises(TransportUnavailable, match="ros2 profile .* cannot hold foxglove.SceneUpdate"):
        Router(
            config(
                {"path": tmp_path / "scene.mcap"},
                route("s", "drake_to_scene_update", "mcap", "/s", SCENE_ROUTE),
            )
        )
    Router(config({"path": existing, "overwrite": True}, poses)).close()
    # a session that wrote no message keeps no file: the one there stays, and no .partial is left
    assert existing.read_bytes() == b"keep" and sorted(tmp_path.iterdir()) == [existing]
    router = Router(config({"path": existing, "overwrite": True}, poses))
    feed(router, "DRAKE_VIEWER_DRAW", draw_of(small_scene(), 1.0), 1_000_000)
    router.close()
    assert [topic for topic, *_ in read(existing)] == ["/poses"]


def test_a_session_that_wrote_no_message_keeps_no_file_and_says_so(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "quiet.mcap"
    with caplog.at_level(logging.INFO, logger="viewer_bridge"):
        Router(
            config({"path": path}, route("poses", "drake_to_pose_array", "mcap", "/poses", DRAW_ROUTE))
        ).close()
    assert not list(tmp_path.iterdir())
    assert f"{path}: no message was written: nothing kept" in caplog.messages


def test_the_foxglove_server_and_a_foxglove_file_share_one_context(tmp_path: Path) -> None:
    from tests.transports.test_foxglove import FoxgloveClient

    path = tmp_path / "session.mcap"
    router = scene_and_frames(path, frames_to="foxglove", foxglove={"port": 0})
    server = router.transports["foxglove"]
    assert isinstance(server, FoxgloveTransport)
    scene = small_scene()
    feed(router, "DRAKE_VIEWER_LOAD_ROBOT", LOAD, 1)
    feed(router, "DRAKE_VIEWER_DRAW", draw_of(scene, 0.0), 2)  # both channels exist from here
    client = FoxgloveClient(server.port)
    draws = 1
    try:
        client.subscribe("/drake/scene", "/drake/transforms")  # the file's channel is served too
        deadline = time.monotonic() + 60
        while "/drake/transforms" not in client.messages and time.monotonic() < deadline:
            feed(router, "DRAKE_VIEWER_DRAW", draw_of(scene, draws / 4), 2 + draws)  # until subscribed
            draws += 1
            client.pump(0.1)
        another_scene = load_from_scene(Scene(scene.links[:1])).encode()
        feed(router, "DRAKE_VIEWER_LOAD_ROBOT", another_scene, 1000)
        feed(router, "DRAKE_VIEWER_DRAW", draw_of(scene, 9.0), 1001)
        draws += 1
        assert client.pump(60, lambda: len(client.messages.get("/drake/scene", [])) == 1), client.log()
    finally:
        client.close()
        router.close()
    with path.open("rb") as file:
        summary = make_reader(file).get_summary()
    assert summary is not None  # one channel per topic, whichever transport made it
    assert sorted(channel.topic for channel in summary.channels.values()) == [
        "/drake/scene",
        "/drake/transforms",
    ]
    written = read(path)
    by_topic: dict[str, list[tuple[int, bytes]]] = {}
    for topic, _, log_time, data in written:
        by_topic.setdefault(topic, []).append((log_time, data))
    # Each message once: the routes' scenes (at their receive time), and the server's transforms.
    assert [log_time for log_time, _ in by_topic["/drake/scene"]] == [1_000, 1_000_000]
    assert len(by_topic["/drake/transforms"]) == draws
    zs = [
        FrameTransforms.FromString(data).transforms[0].translation.z
        for _, data in by_topic["/drake/transforms"]
    ]
    assert zs == [index / 4 for index in range(draws - 1)] + [9.0]
    assert client.messages["/drake/scene"] == [by_topic["/drake/scene"][1][1]]


def test_one_topic_routed_to_both_the_server_and_the_file_is_warned_about(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    router = Router(
        config(
            {"path": tmp_path / "twice.mcap", "profile": "foxglove"},
            route("live", "drake_to_frame_transforms", "foxglove", "/drake/transforms", DRAW_ROUTE),
            route("file", "drake_to_frame_transforms", "mcap", "/drake/transforms", DRAW_ROUTE),
            foxglove={"port": 0, "accept_websocket_v1": False},
        )
    )
    with caplog.at_level(logging.WARNING, "viewer_bridge"):
        feed(router, "DRAKE_VIEWER_DRAW", draw_of(small_scene(), 0.0), 1)
    router.close()
    assert "/drake/transforms is routed to both the foxglove and the mcap transport" in caplog.text


# --- any LCM type: `viewer-bridge convert` writes /lcm/<channel> in both profiles ----------------------

from tests.translators.test_lcm_generic import CORPUS, arm_status, assert_same, lcmgen_corpus  # noqa: E402, F401


def any_types_log(path: Path, extra: list[Any] = ()) -> Path:  # type: ignore[assignment]
    """Drake's driver messages, the viewer's scene, a channel of no known type, and `extra` events."""
    import drake as drake_lcmtypes

    from tests.drake_robot_status import iiwa_status, robot_plan
    from viewer_bridge.transports.lcm import LcmEvent, write_log

    events = [LcmEvent("DRAKE_VIEWER_LOAD_ROBOT", LOAD, 1_000)]
    for step in range(5):
        time_us = 10_000 * (step + 1)
        events.append(LcmEvent("IIWA_STATUS", iiwa_status(step / 100).encode(), time_us))
        events.append(LcmEvent("DRAKE_VIEWER_DRAW", draw_of(small_scene(), step / 100), time_us + 1))
        events.append(LcmEvent("MYSTERY", b"\x01\x02\x03\x04\x05\x06\x07\x08?", time_us + 2))
    events.append(LcmEvent("ROBOT_PLAN", robot_plan(0.5).encode(), 90_000))
    events.append(LcmEvent("left-arm.command", drake_lcmtypes.lcmt_iiwa_command().encode(), 91_000))
    write_log(path, [*events, *extra])
    return path


def cli(*args: str) -> Any:
    import subprocess
    import sys

    command = [sys.executable, "-m", "viewer_bridge.cli.main", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


def read_mcap(path: Path) -> dict[str, list[Any]]:
    """topic -> (schema name, schema encoding, message encoding, log time, message, schema, channel)."""
    found: dict[str, list[Any]] = {}
    with path.open("rb") as file:
        reader = make_reader(file)
        for schema, channel, message in reader.iter_messages():
            entry = (schema.name if schema else None, schema.encoding if schema else None,
                     channel.message_encoding, message.log_time)  # fmt: skip
            found.setdefault(channel.topic, []).append((*entry, message, schema, channel))
    return found


@pytest.mark.parametrize("profile", ["ros2", "foxglove"])
def test_convert_writes_every_channel_of_a_known_type_with_no_flag(profile: str, tmp_path: Path) -> None:
    import drake as drake_lcmtypes
    from mcap_ros2._dynamic import generate_dynamic

    log = any_types_log(tmp_path / "robot.lcmlog")
    out = tmp_path / "robot.mcap"
    result = cli("convert", str(log), str(out), "--schema", profile)
    assert result.returncode == 0, result.stderr
    topics = read_mcap(out)
    assert {"/lcm/IIWA_STATUS", "/lcm/ROBOT_PLAN", "/lcm/left_arm_command"} <= set(topics)
    assert not [topic for topic in topics if topic.startswith("/lcm/DRAKE_") or "MYSTERY" in topic]
    viewer = {"/drake/poses", "/tf"} if profile == "ros2" else {"/drake/scene", "/drake/transforms"}
    assert viewer <= set(topics), set(topics)  # beside the translated viewer topics
    assert "skipped: 5 messages on MYSTERY: unknown_type" in result.stderr  # said, not written
    from viewer_bridge.transports.lcm import read_log

    sent: dict[str, list[Any]] = {}
    for event in read_log(log):
        sent.setdefault(event.channel, []).append(event)
    for topic, channel, lcm_class, name in (
        ("/lcm/IIWA_STATUS", "IIWA_STATUS", drake_lcmtypes.lcmt_iiwa_status, "LcmtIiwaStatus"),
        ("/lcm/ROBOT_PLAN", "ROBOT_PLAN", drake_lcmtypes.lcmt_robot_plan, "LcmtRobotPlan"),
    ):
        written = topics[topic]
        assert len(written) == len(sent[channel])
        for (schema_name, schema_encoding, encoding, log_time, message, schema, _), event in zip(
            written, sent[channel], strict=True
        ):
            assert (schema_name, schema_encoding, encoding) == (
                f"drake_lcm_msgs/msg/{name}",
                "ros2msg",
                "cdr",
            )
            assert log_time == event.timestamp_us * 1000  # the log's own time
            decoded = generate_dynamic(schema_name, schema.data.decode())[schema_name](message.data)
            assert_same(lcm_class.decode(event.data), decoded)


def test_convert_lcm_channels_chooses_the_channels_of_any_type(tmp_path: Path) -> None:
    log = any_types_log(tmp_path / "robot.lcmlog")
    out = tmp_path / "robot.mcap"
    # Groups of its own shift the route's: the topic is still the channel's.
    result = cli("convert", str(log), str(out), "--lcm-channels", "(IIWA)_STATUS|ROBOT_(PLAN)")
    assert result.returncode == 0, result.stderr
    topics = set(read_mcap(out))
    assert {"/lcm/IIWA_STATUS", "/lcm/ROBOT_PLAN"} <= topics and "/lcm/left_arm_command" not in topics
    assert "/drake/poses" in topics  # the viewer's routes are not narrowed


def test_convert_lcm_types_adds_a_labs_own_folder(
    tmp_path: Path,
    lcmgen_corpus: dict[str, type],  # noqa: F811 (the fixture, imported)
) -> None:
    from mcap_ros2._dynamic import generate_dynamic

    from viewer_bridge.transports.lcm import LcmEvent

    data = arm_status(lcmgen_corpus).encode()
    log = any_types_log(tmp_path / "lab.lcmlog", [LcmEvent("ARM_STATUS", data, 95_000)])
    without = cli("convert", str(log), str(tmp_path / "without.mcap"))
    assert without.returncode == 0 and "ARM_STATUS" in without.stderr and "unknown_type" in without.stderr
    assert "/lcm/ARM_STATUS" not in read_mcap(tmp_path / "without.mcap")
    out = tmp_path / "with.mcap"
    result = cli("convert", str(log), str(out), "--lcm-types", str(CORPUS))
    assert result.returncode == 0, result.stderr
    [(name, _, _, _, message, schema, _)] = read_mcap(out)["/lcm/ARM_STATUS"]
    assert name == "vbtest_lab_lcm_msgs/msg/ArmStatusT"
    decoded = generate_dynamic(name, schema.data.decode())[name](message.data)
    assert_same(lcmgen_corpus["vbtest_lab.arm_status_t"].decode(data), decoded)
