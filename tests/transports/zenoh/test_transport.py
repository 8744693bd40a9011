"""The Zenoh transport end to end: the bridge as a process, a Zenoh router from eclipse-zenoh itself
(on 127.0.0.1 and a free port), and an rmw_zenoh node written in tests/zenoh_peers.py from
rmw_zenoh's design document. LCM across networks: two bridges, real pydrake on one side."""

from __future__ import annotations

import contextlib
import os
import struct
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest
import xxhash
import yaml
from rosbags.typesys import Stores, get_typestore

from tests.peers import BridgeProcess, wait_for, write_config
from tests.test_router import LcmRecorder, start_drake
from tests.zenoh_peers import (
    RmwZenohPeer,
    Router,
    RouterProcess,
    data_key,
    decode,
    free_lcm_url,
    free_port,
    stats_flags,
    stats_of,
    written_stats,
)
from viewer_bridge.config.bridge import load_config
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.model.scene import Box, Geometry, Link, LinkPoses, Scene
from viewer_bridge.transports.lcm import LcmBus

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
DOMAIN = int(os.environ["ROS_DOMAIN_ID"])  # this test process's own (tests/conftest.py)
STORE = get_typestore(Stores.ROS2_JAZZY)

DRAWS_OVER_ZENOH = """\
routes:
  - name: poses
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: drake_to_pose_array
    destination: {transport: zenoh, name: drake/poses}
    qos: {depth: 100}
    rate: {policy: all}
  - name: tf
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"}
    translator: drake_to_tf
    destination: {transport: zenoh, name: /tf}
    qos: {depth: 100}
    rate: {policy: all}
  - name: link_markers
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"}
    translator: drake_to_link_markers
    destination: {transport: zenoh, name: drake/link_markers}
"""

SCENE = Scene(
    tuple(Link(f"plant::robot::link{index}", 1, (Geometry(Box((0.1, 0.2, 0.3))),)) for index in range(3))
    + (Link("plant::robot::fixed", 1, (Geometry(Box((1.0, 1.0, 0.1))),)),)  # never drawn: /tf_static
)
DRAWN = tuple(link.name for link in SCENE.links[:3])


def draw(sequence: int) -> tuple[LinkPoses, bytes]:
    positions = np.array([[sequence, 0.5 * index, -0.25] for index in range(3)], float)
    angle = 0.1 * sequence
    quaternions = np.array([[np.cos(angle), 0.0, 0.0, np.sin(angle)]] * 3)  # w, x, y, z
    poses = LinkPoses(sequence, DRAWN, np.ones(3, np.int32), positions, quaternions)
    return poses, DrawEncoder().encode(poses)


def on_the_wire(poses: LinkPoses) -> tuple[list[list[float]], list[list[float]]]:
    """Positions and w-x-y-z quaternions as lcmt_viewer_draw carries them: float32."""
    return poses.positions.astype(np.float32).tolist(), poses.quaternions_wxyz.astype(np.float32).tolist()


def bridge(endpoint: str, *args: str, stats: Path | None = None) -> BridgeProcess:
    return BridgeProcess(
        *args, "--set", f"zenoh.connect=[{endpoint}]", *(stats_flags(stats) if stats else [])
    )


def zenoh_errors(path: Path) -> dict[str, int]:
    return written_stats(path).get("transports", {}).get("zenoh", {}).get("errors", {})  # type: ignore[no-any-return]


@contextlib.contextmanager
def drawing(url: str, period_s: float, load: bool = False) -> Iterator[None]:
    """Draws of SCENE published on `url` every `period_s` seconds (after its load, if asked) while inside."""
    bus = LcmBus(url)
    stop = threading.Event()

    def keep_drawing() -> None:
        if load:
            bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(SCENE).encode())
        sequence = 0
        while not stop.wait(period_s):
            sequence += 1
            bus.publish("DRAKE_VIEWER_DRAW", draw(sequence)[1])

    thread = threading.Thread(target=keep_drawing)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        bus.close()


@pytest.fixture
def router() -> Any:
    running = Router()
    yield running
    running.close()


def bridge_token(peer: RmwZenohPeer, part: str) -> str | None:
    """The bridge's token (node viewer_bridge) that contains `part`, if the graph has it."""
    return next((token for token in peer.tokens() if "/viewer_bridge" in token and part in token), None)


# --- ROS 2 in rmw_zenoh's wire format -----------------------------------------------------------------


def test_a_draw_reaches_an_rmw_zenoh_subscriber_as_poses_and_tf(router: Router, tmp_path: Path) -> None:
    url = free_lcm_url()
    peer = RmwZenohPeer(router.endpoint, DOMAIN)
    poses_in = peer.subscribe("/drake/poses", "geometry_msgs/msg/PoseArray")
    tf_in = peer.subscribe("/tf", "tf2_msgs/msg/TFMessage")
    process = bridge(router.endpoint, "-c", str(write_config(tmp_path, DRAWS_OVER_ZENOH)), "--lcm-url", url)
    bus = LcmBus(url)
    sent: dict[int, LinkPoses] = {}
    try:
        process.wait_for_line(" running (")
        assert wait_for(lambda: bridge_token(peer, "/NN/") is not None)  # publishers come with the first draw
        bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(SCENE).encode())
        sequence = 0
        while len(poses_in) < 5 and sequence < 600:  # until five have arrived (UDP may drop one)
            sequence += 1
            sent[sequence], data = draw(sequence)
            bus.publish("DRAKE_VIEWER_DRAW", data)
            time.sleep(0.1)
        assert wait_for(lambda: len(tf_in) >= 5)
        tokens = peer.tokens()
    finally:
        assert process.stop() == 0
        bus.close()
        peer.close()
    # Keys: <domain>/<topic>/<DDS type>/<RIHS01 hash>.
    assert {arrival.key for arrival in poses_in} == {
        data_key(DOMAIN, "/drake/poses", "geometry_msgs/msg/PoseArray")
    }
    assert {arrival.key for arrival in tf_in} == {data_key(DOMAIN, "/tf", "tf2_msgs/msg/TFMessage")}
    # Tokens: the node, and a publisher per topic with its QoS (reliable, depth 100; /tf_static and
    # the link markers TRANSIENT_LOCAL).
    (node,) = [token for token in tokens if token.endswith("/NN/%/%/viewer_bridge")]
    zid = node.split("/")[2]
    assert node == f"@ros2_lv/{DOMAIN}/{zid}/0/0/NN/%/%/viewer_bridge"
    publishers = {token.split("/")[9]: token for token in tokens if f"/{zid}/0/" in token and "/MP/" in token}
    assert set(publishers) == {"%drake%poses", "%tf", "%tf_static", "%drake%link_markers"}
    assert publishers["%drake%poses"].endswith(
        "/MP/%/%/viewer_bridge/%drake%poses/geometry_msgs::msg::dds_::PoseArray_/"
        + STORE.hash_rihs01("geometry_msgs/msg/PoseArray")
        + "/::,100:,:,:,,"
    )
    assert publishers["%tf_static"].endswith("/:1:,100:,:,:,,")
    assert publishers["%drake%link_markers"].endswith("/:1:,10:,:,:,,")
    # Attachments: sequence numbers one apart, a source time before arrival, the GID of the token.
    digest = xxhash.xxh3_128_intdigest(publishers["%drake%poses"].encode())
    gid = struct.pack("<QQ", digest & (2**64 - 1), digest >> 64)
    stamps = []
    for arrival in poses_in:
        assert arrival.attachment is not None and len(arrival.attachment) == 33
        number, source_ns, length = struct.unpack_from("<qqB", arrival.attachment)
        assert (length, arrival.attachment[17:]) == (16, gid)
        assert time.time_ns() - 600e9 < source_ns <= arrival.at_ns
        stamps.append(number)
    assert np.all(np.diff(stamps) == 1)
    # Payloads: CDR with its encapsulation header, equal to the draws.
    for arrival in poses_in:
        assert arrival.payload[:4] == b"\x00\x01\x00\x00"
        message = decode(arrival, "geometry_msgs/msg/PoseArray")
        poses = sent[round(message.poses[0].position.x)]
        for pose, position, (w, x, y, z) in zip(message.poses, *on_the_wire(poses), strict=True):
            assert [pose.position.x, pose.position.y, pose.position.z] == list(position)
            assert [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w] == [
                x,
                y,
                z,
                w,
            ]
    for arrival in tf_in:
        transforms = decode(arrival, "tf2_msgs/msg/TFMessage").transforms
        assert [t.child_frame_id for t in transforms] == [name.replace("::", "/") for name in DRAWN]
        poses = sent[round(transforms[0].transform.translation.x)]
        for transform, position, (w, x, y, z) in zip(transforms, *on_the_wire(poses), strict=True):
            translation, rotation = transform.transform.translation, transform.transform.rotation
            assert transform.header.frame_id == "world"
            assert [translation.x, translation.y, translation.z] == list(position)
            assert [rotation.x, rotation.y, rotation.z, rotation.w] == [x, y, z, w]


def test_a_late_subscriber_gets_tf_static_and_the_model(router: Router, tmp_path: Path) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    process = bridge(router.endpoint, "-c", str(write_config(tmp_path, DRAWS_OVER_ZENOH)), "--lcm-url", url,
                     stats=stats)  # fmt: skip
    bus = LcmBus(url)
    try:
        process.wait_for_line(" running (")
        sent = lambda route: stats_of(stats).get(route, {}).get("messages_out", 0)  # noqa: E731

        def published() -> bool:  # the load (UDP may drop one), then a draw: /tf_static and the markers
            if sent("link_markers") == 0 or sent("tf") < 2:
                bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(SCENE).encode())
                bus.publish("DRAKE_VIEWER_DRAW", draw(1)[1])
                time.sleep(0.2)
            return sent("link_markers") >= 1 and sent("tf") >= 2

        assert wait_for(published)
        # Only now does the subscriber start: it asks the publishers' caches, as rmw_zenoh's
        # TRANSIENT_LOCAL subscriptions do.
        late = RmwZenohPeer(router.endpoint, DOMAIN, node="late")
        static = late.subscribe("/tf_static", "tf2_msgs/msg/TFMessage", latched=True, depth=1)
        markers = late.subscribe("/drake/link_markers", "visualization_msgs/msg/MarkerArray", latched=True)
        try:
            assert wait_for(lambda: len(static) >= 1 and len(markers) >= 1)
        finally:
            late.close()
    finally:
        assert process.stop() == 0
        bus.close()
    transforms = decode(static[0], "tf2_msgs/msg/TFMessage").transforms
    assert [(t.header.frame_id, t.child_frame_id) for t in transforms] == [("world", "plant/robot/fixed")]
    array = decode(markers[0], "visualization_msgs/msg/MarkerArray").markers
    assert array[0].action == 3 and len(array) == 1 + len(SCENE.links)  # DELETEALL, then every link's box
    assert len(static[0].attachment or b"") == 33


ZENOH_TO_LCM = """\
routes:
  - name: from_zenoh
    source: {transport: zenoh, name: "/drake_in/(.*)"}
    translator: ros_pose_array_to_drake_draw
    destination: {transport: lcm, name: "DRAKE_VIEWER_DRAW_FROM_{1:topic}"}
    rate: {policy: all}
    options: {link_names: ["plant::a", "plant::b"], robot_nums: [2, 3]}
"""


def pose_array(x: float) -> bytes:
    message = STORE.types["geometry_msgs/msg/PoseArray"]
    header = STORE.types["std_msgs/msg/Header"](
        STORE.types["builtin_interfaces/msg/Time"](12, 345_000_000), "world"
    )
    Pose, Point, Quaternion = (
        STORE.types[f"geometry_msgs/msg/{name}"] for name in ("Pose", "Point", "Quaternion")
    )
    poses = [Pose(Point(x + index, 0.5, -0.25), Quaternion(0.0, 0.0, 0.6, 0.8)) for index in range(2)]
    return bytes(STORE.serialize_cdr(message(header, poses), "geometry_msgs/msg/PoseArray"))


def test_a_pose_array_from_rmw_zenoh_reaches_lcm_and_bad_samples_are_counted(
    router: Router, tmp_path: Path
) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    peer = RmwZenohPeer(router.endpoint, DOMAIN, node="camera")
    publish = peer.publisher("/drake_in/poses", "geometry_msgs/msg/PoseArray")
    # Junk in the graph: a token the bridge cannot parse is counted, not fatal.
    junk = peer.session.liveliness().declare_token(
        f"@ros2_lv/{DOMAIN}/{peer.zid}/0/9/MS/%/%/camera/%x/T/H/::"
    )
    process = bridge(router.endpoint, "-c", str(write_config(tmp_path, ZENOH_TO_LCM)), "--lcm-url", url,
                     stats=stats)  # fmt: skip
    arrived = lambda: recorder.messages.get("DRAKE_VIEWER_DRAW_FROM_poses", [])  # noqa: E731
    try:
        process.wait_for_line(" running (")
        # The route's source is a regex: the bridge subscribes once the graph shows the publisher.
        assert wait_for(lambda: bridge_token(peer, "/MS/") is not None)
        publish(pose_array(100.0), attachment=b"\x01\x02")  # a malformed attachment
        publish(pose_array(100.0), attachment=b"")  # an empty one
        publish(b"<html>not CDR</html>")  # no CDR encapsulation header
        publish(b"\x00\x01\x00\x00\xff")  # CDR's header, then not a PoseArray: the route's error
        assert wait_for(lambda: zenoh_errors(stats).get("not_cdr", 0) >= 1)
        publish(pose_array(1.0))
        assert wait_for(lambda: len(arrived()) >= 1)
        assert wait_for(lambda: stats_of(stats).get("from_zenoh", {}).get("errors"))
        errors, route_errors = zenoh_errors(stats), stats_of(stats)["from_zenoh"]["errors"]
    finally:
        assert process.stop() == 0
        recorder.close()
        del junk
        peer.close()
    assert errors["bad_attachment"] == 2 and errors["not_cdr"] == 1 and errors["bad_token"] >= 1
    assert route_errors == {"DecodeError": 1}
    (data,) = arrived()
    message = drake_lcmtypes.lcmt_viewer_draw.decode(data)  # Drake's own class reads it
    assert message.timestamp == 12_345 and list(message.link_name) == ["plant::a", "plant::b"]
    assert [list(p) for p in message.position] == [[1.0, 0.5, -0.25], [2.0, 0.5, -0.25]]
    assert np.allclose(message.quaternion, [[0.8, 0.0, 0.0, 0.6]] * 2)


# --- builtin:zenoh --------------------------------------------------------------------------------------


def test_builtin_zenoh_is_the_default_configs_ros_routes_over_zenoh() -> None:
    default, over_zenoh = load_config("builtin:default"), load_config("builtin:zenoh")
    expected = [
        route.model_dump()
        for route in default.routes
        if "ros" in (route.source.transport, route.destination.transport)
    ]
    for route in expected:
        for end in ("source", "destination"):
            if route[end]["transport"] == "ros":
                route[end]["transport"] = "zenoh"
    assert [route.model_dump() for route in over_zenoh.routes] == expected


LAZY = """\
routes:
  - name: tf
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"}
    translator: drake_to_tf
    destination: {transport: zenoh, name: /tf}
    lazy: true
  - name: poses
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: drake_to_pose_array
    destination: {transport: zenoh, name: drake/poses}
    lazy: true
"""


def test_lazy_routes_wake_on_an_rmw_zenoh_subscriber_or_any_zenoh_subscriber(
    router: Router, tmp_path: Path
) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    process = bridge(router.endpoint, "-c", str(write_config(tmp_path, LAZY)), "--lcm-url", url, stats=stats)
    state = lambda route: stats_of(stats).get(route, {}).get("state")  # noqa: E731
    peer = RmwZenohPeer(router.endpoint, DOMAIN, node="viewer")
    try:
        process.wait_for_line(" running (")
        with drawing(url, 0.05, load=True):
            assert wait_for(lambda: state("tf") == state("poses") == "idle: no subscriber")
            # An rmw_zenoh subscriber's token alone wakes /tf ...
            hash_ = STORE.hash_rihs01("tf2_msgs/msg/TFMessage")
            token = f"@ros2_lv/{DOMAIN}/{peer.zid}/0/1/MS/%/%/viewer/%tf/tf2_msgs::msg::dds_::TFMessage_/{hash_}/::,:,:,:,,"
            held = peer.session.liveliness().declare_token(token)
            assert wait_for(lambda: state("tf") == "active")
            assert state("poses") == "idle: no subscriber"
            # ... and a plain Zenoh subscriber, without a token, wakes the poses.
            plain = peer.session.declare_subscriber(f"{DOMAIN}/drake/poses/**", lambda sample: None)
            assert wait_for(lambda: state("poses") == "active")
            del held, plain
    finally:
        assert process.stop() == 0
        peer.close()


def test_the_bridge_as_a_router_dials_no_router_counts_nothing_unsent_and_serves_its_clients(
    tmp_path: Path,
) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    config = str(write_config(tmp_path, DRAWS_OVER_ZENOH))
    process = BridgeProcess("-c", config, "--lcm-url", url, "--set", "zenoh.mode=router",
                            "--set", f"zenoh.listen=[{endpoint}]", *stats_flags(stats))  # fmt: skip
    route = lambda name: stats_of(stats).get(name, {})  # noqa: E731
    try:
        start = process.wait_for_line(" running (")
        assert f"Zenoh router, listening on {endpoint}:" in start  # and dialing nothing
        with drawing(url, 0.05, load=True):
            # No one connected: published into a router no one reaches, which is no loss.
            assert wait_for(lambda: route("poses").get("messages_out", 0) >= 5)
            assert route("poses").get("unsent", 0) == 0
            assert "unsent_no_router" not in zenoh_errors(stats)
            peer = RmwZenohPeer(endpoint, DOMAIN)  # a client of the bridge itself
            try:
                poses_in = peer.subscribe("/drake/poses", "geometry_msgs/msg/PoseArray")
                assert wait_for(lambda: len(poses_in) >= 3)
            finally:
                peer.close()
        assert "unsent_no_router" not in zenoh_errors(stats)
    finally:
        assert process.stop() == 0
    assert not any("7447" in line for line in process.lines)


# --- a router that is down at start, killed and started again --------------------------------------------


def empty_cloud() -> bytes:
    types = STORE.types
    header = types["std_msgs/msg/Header"](types["builtin_interfaces/msg/Time"](0, 0), "world")
    cloud = types["sensor_msgs/msg/PointCloud2"](header, 1, 0, [], False, 0, 0, np.zeros(0, np.uint8), True)
    return bytes(STORE.serialize_cdr(cloud, "sensor_msgs/msg/PointCloud2"))


def test_a_bridge_with_traffic_both_ways_stops_cleanly_every_time(router: Router) -> None:
    """SIGINT while Zenoh calls back on its own threads (samples in, matching and graph events)
    and the routes publish: the process exits 0, every time. A callback entering Python while
    the interpreter finalises would abort it (-6, "FATAL: exception not rethrown"): `Link.close`
    ends them first, and they are no daemons, so the interpreter waits for them at exit (the
    loop that catches that abort: tests/transports/zenoh/test_exit.py). 8 stops."""
    url = free_lcm_url()
    peer = RmwZenohPeer(router.endpoint, DOMAIN)
    poses = peer.subscribe("/drake/poses", "geometry_msgs/msg/PoseArray")
    publish, cloud = peer.publisher("/drake_in/point_cloud", "sensor_msgs/msg/PointCloud2"), empty_cloud()
    stop = threading.Event()

    def flood() -> None:  # samples for the bridge's subscription, all the while
        while not stop.wait(0.001):
            publish(cloud)

    flooder = threading.Thread(target=flood)
    flooder.start()
    try:
        with drawing(url, 0.002, load=True):
            for attempt in range(8):
                process = bridge(router.endpoint, "-c", "builtin:zenoh", "--lcm-url", url)
                try:
                    process.wait_for_line(" running (")
                    before = len(poses)
                    assert wait_for(lambda: len(poses) > before + 5), f"no poses from bridge {attempt}"  # noqa: B023
                finally:
                    code = process.stop()
                assert code == 0, f"stop {attempt}: exit code {code}; its log:\n" + "\n".join(process.lines)
    finally:
        stop.set()
        flooder.join(timeout=60)
        peer.close()


def test_the_bridge_waits_for_the_router_and_recovers_when_it_restarts(tmp_path: Path) -> None:
    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    router = RouterProcess()
    process = bridge(router.endpoint, "-c", str(write_config(tmp_path, DRAWS_OVER_ZENOH)), "--lcm-url", url,
                     stats=stats)  # fmt: skip
    unsent = lambda: zenoh_errors(stats).get("unsent_no_router", 0)  # noqa: E731
    peer = None
    try:
        process.wait_for_line(" running (")  # with no router: the other routes run meanwhile
        with drawing(url, 0.01):  # 100 Hz
            assert wait_for(lambda: unsent() > 0)
            router.start()
            peer = RmwZenohPeer(router.endpoint, DOMAIN)
            poses = peer.subscribe("/drake/poses", "geometry_msgs/msg/PoseArray")
            assert wait_for(lambda: len(poses) > 10)
            before = unsent()
            router.kill()
            assert wait_for(lambda: unsent() > before)  # counted while the router is away
            up = router.start()
            count = len(poses)
            assert wait_for(lambda: len(poses) > count)
            recovery = time.monotonic() - up
            # The bridge's node and publishers are in the new router's graph again.
            assert wait_for(
                lambda: bridge_token(peer, "/NN/") is not None and bridge_token(peer, "%drake%poses")
            )
        print(f"\nZenoh router restart: samples flow again {recovery:.2f} s after the router is back")
    finally:
        assert process.stop() == 0
        if peer is not None:
            peer.close()
        router.kill()
    assert stats_of(stats)["poses"]["errors"] == {}


# --- LCM across networks: two bridges, two LCM buses, one router ----------------------------------------


def test_two_bridges_join_two_lcm_buses_and_a_late_viewer_gets_the_load(
    router: Router, tmp_path: Path
) -> None:
    sim_url, viewer_url, late_url = free_lcm_url(), free_lcm_url(), free_lcm_url()
    sim, viewer, late = LcmRecorder(sim_url), LcmRecorder(viewer_url), LcmRecorder(late_url)
    simulation_side = bridge(router.endpoint, "-c", "builtin:lcm-to-zenoh", "--lcm-url", sim_url)
    viewer_side = bridge(router.endpoint, "-c", "builtin:zenoh-to-lcm", "--lcm-url", viewer_url)
    late_side = None
    load, draws = "DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION", "DRAKE_VIEWER_DRAW_ILLUSTRATION"
    try:
        simulation_side.wait_for_line(" running (")
        viewer_side.wait_for_line(" running (")
        assert start_drake(sim_url, tmp_path, 2.0).wait(timeout=120) == 0
        sim.sync()  # holds Drake's last draw
        last_draw = sim.messages[draws][-1]
        assert wait_for(lambda: last_draw in viewer.messages.get(draws, [])), (
            {k: len(v) for k, v in viewer.messages.items()},
            {k: len(v) for k, v in sim.messages.items()},
            simulation_side.lines[-5:],
            viewer_side.lines[-5:],
        )
        # A viewer side that joins after the simulation has sent its one load still gets it.
        late_side = bridge(router.endpoint, "-c", "builtin:zenoh-to-lcm", "--lcm-url", late_url)
        late_side.wait_for_line(" running (")
        assert wait_for(lambda: load in late.messages and draws in late.messages), (
            {k: len(v) for k, v in late.messages.items()},
            late_side.lines[-5:],
        )
    finally:
        for process in (simulation_side, viewer_side, late_side):
            if process is not None:
                assert process.stop() == 0
        for recorder in (sim, viewer, late):
            recorder.close()
    assert viewer.messages[load] == sim.messages[load]
    assert late.messages[load] == sim.messages[load][-1:]
    assert late.messages[draws] == [last_draw]  # the last one, kept for late joiners
    message = drake_lcmtypes.lcmt_viewer_draw.decode(last_draw)  # Drake's own class reads it
    assert message.num_links == len(message.link_name) > 0
    received = [drake_lcmtypes.lcmt_viewer_draw.decode(data).timestamp for data in viewer.messages[draws]]
    assert received == sorted(received)  # in order; `latest` may skip some, never reorders


def test_lcm_channels_that_are_no_zenoh_keys_are_refused() -> None:
    from viewer_bridge.transports.zenoh.transport import ZenohTransport

    for name in ("", "a//b", "a/*", "trailing/"):
        with pytest.raises(ValueError, match="cannot be a Zenoh key"):
            ZenohTransport.check_destination(name)
    ZenohTransport.check_destination("DIRECTOR_TREE_VIEWER_RESPONSE_<client 1>")
    assert yaml.safe_load("[tcp/127.0.0.1:7447]") == [
        "tcp/127.0.0.1:7447"
    ]  # what --set zenoh.connect=[...] gives


# --- any LCM type: Drake's driver messages from a pydrake diagram ------------------------------------------


def independent_store() -> Any:
    """A rosbags store of its own holding the mapped types' .msg definitions: the reader's view of
    the types (their RIHS01 hashes and CDR layout), not the bridge's transcoder."""
    from rosbags.typesys import get_types_from_msg

    from viewer_bridge.lcmcodec.library import TypeLibrary

    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in TypeLibrary.load().ros_definitions().items():
        store.register(get_types_from_msg(text, name))
    return store


def test_any_lcm_type_from_a_pydrake_diagram_reaches_an_rmw_zenoh_subscriber(
    router: Router, tmp_path: Path
) -> None:
    from tests.conftest import SYNC_CHANNEL
    from tests.drake_robot_status import PLAN_CHANNEL, STATUS_CHANNEL, drive_until
    from tests.test_router import LcmRecorder
    from tests.translators.test_lcm_generic import assert_same

    url = free_lcm_url()
    stats = tmp_path / "stats.json"
    recorder = LcmRecorder(url)
    process = bridge(router.endpoint, "-c", "builtin:zenoh", "--lcm-url", url, stats=stats)
    peer = RmwZenohPeer(router.endpoint, DOMAIN, node="plotter")
    arrived: dict[str, list[tuple[str, bytes]]] = {STATUS_CHANNEL: [], PLAN_CHANNEL: []}
    lock = threading.Lock()

    def keep(channel: str) -> Any:
        def on_sample(sample: Any) -> None:
            with lock:
                arrived[channel].append((str(sample.key_expr), sample.payload.to_bytes()))

        return on_sample

    # Any type on the topic: the key's type and hash parts are checked below. A subscriber wakes the lazy route.
    subscribers = [
        peer.session.declare_subscriber(f"{DOMAIN}/lcm/{channel}/**", keep(channel)) for channel in arrived
    ]
    store = independent_store()
    try:
        process.wait_for_line("routes running")
        # The lazy route wakes once it sees the subscribers: the driver publishes until they have their share.
        assert drive_until(
            url, lambda: len(arrived[STATUS_CHANNEL]) >= 100 and len(arrived[PLAN_CHANNEL]) >= 10
        ), ({channel: len(samples) for channel, samples in arrived.items()}, process.lines)
        recorder.sync()  # holds every message the driver sent
    finally:
        assert process.stop() == 0
        del subscribers
        peer.close()
        recorder.close()
    sent = {
        channel: {type(message).decode(data).utime: data for data in recorder.messages[channel]}
        for channel, message in ((STATUS_CHANNEL, drake_lcmtypes.lcmt_iiwa_status()),
                                 (PLAN_CHANNEL, drake_lcmtypes.lcmt_robot_plan()))
    }  # fmt: skip
    for channel, typename, lcm_class in (
        (STATUS_CHANNEL, "drake_lcm_msgs/msg/LcmtIiwaStatus", drake_lcmtypes.lcmt_iiwa_status),
        (PLAN_CHANNEL, "drake_lcm_msgs/msg/LcmtRobotPlan", drake_lcmtypes.lcmt_robot_plan),
    ):
        for key, payload in arrived[channel]:
            assert key.split("/")[-2:] == [f"drake_lcm_msgs::msg::dds_::{typename.split('/')[-1]}_",
                                           store.hash_rihs01(typename)]  # fmt: skip
            message = store.deserialize_cdr(payload, typename)
            assert_same(lcm_class.decode(sent[channel][message.utime]), message)
    route = stats_of(stats)["lcm_bus"]
    # the recorder's mark
    assert route["errors"] == {} and route["held"] == {SYNC_CHANNEL: {"unknown_type": 1}}
