"""The tree viewer, both sides: a client written from the spec drives viewer-bridge's server, and
viewer-bridge's client recovers from a viewer that lost its tree.

The client here builds its JSON by hand from docs/PROTOCOLS.md section 2 and its envelopes with
lcm-gen's own `viewer2_comms_t` class, so it shares no code with the bridge.
"""

from __future__ import annotations

import contextlib
import json
import random
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from visualization_msgs.msg import Marker, MarkerArray

from tests.conftest import lcm_url
from tests.peers import BridgeProcess, RosProbe, write_config
from viewer_bridge.errors import BridgeError
from viewer_bridge.examples.demo import DEMO_MESH
from viewer_bridge.examples.scenes import draw_of, small_scene
from viewer_bridge.formats.drake.load import decode_load, load_from_scene
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS
from viewer_bridge.model.scene import Pose
from viewer_bridge.translators.tree_viewer import DrakeToTreeViewer, TreeViewerServer
from viewer_bridge.transports.base import Received
from viewer_bridge.transports.lcm import LcmBus

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)

REQUEST = "DIRECTOR_TREE_VIEWER_REQUEST_<spec client>"
RESPONSE = "DIRECTOR_TREE_VIEWER_RESPONSE_<spec client>"


class SpecClient:
    """Envelopes made and read with lcm-gen's class; payloads written from the spec."""

    def __init__(self, lcmgen: dict[str, type]) -> None:
        self.envelope = lcmgen["robotlocomotion.viewer2_comms_t"]

    def wrap(self, payload: Any, format_name: str = "treeviewer_json", major: int = 1) -> bytes:
        message = self.envelope()
        data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
        message.utime = 1
        message.format = format_name
        message.format_version_major, message.format_version_minor = major, 0
        message.num_bytes, message.data = len(data), data
        return bytes(message.encode())

    def read(self, data: bytes) -> dict[str, Any]:
        message = self.envelope.decode(data)
        assert (message.format, message.format_version_major, message.format_version_minor) == (
            "treeviewer_json",
            1,
            0,
        )
        return dict(json.loads(bytes(message.data)))


def request(**commands: Any) -> dict[str, Any]:
    return {
        "timestamp": 1_700_000_000_000_000,
        "setgeometry": [],
        "settransform": [],
        "delete": [],
        **commands,
    }


def every_geometry(mesh: str) -> list[tuple[dict[str, Any], int, int]]:
    """(geometry, marker type, marker count) for all 11 types of the spec."""
    return [
        ({"type": "box", "lengths": [1, 0.5, 2], "color": [1, 0, 0, 0.5]}, Marker.CUBE, 1),
        ({"type": "sphere", "radius": 0.5}, Marker.SPHERE, 1),
        ({"type": "cylinder", "radius": 0.1, "length": 0.4}, Marker.CYLINDER, 1),
        ({"type": "capsule", "radius": 0.1, "length": 0.4}, Marker.CYLINDER, 3),
        ({"type": "ellipsoid", "radii": [0.1, 0.2, 0.3]}, Marker.SPHERE, 1),
        ({"type": "mesh_file", "filename": mesh, "scale": 2}, Marker.MESH_RESOURCE, 1),
        ({"type": "mesh_data", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]},
         Marker.TRIANGLE_LIST, 1),
        ({"type": "pointcloud", "points": [[0, 0, 0], [1, 1, 1]], "channels": {"rgb": [[1, 0, 0], [0, 0, 1]],
                                                                              "intensity": [5, 6]}}, Marker.POINTS, 1),
        ({"type": "planar_lidar", "ranges": [1, 2, 3], "angle_start": 0, "angle_step": 1.5707963267948966},
         Marker.POINTS, 1),
        ({"type": "triad", "scale": 0.5, "tube": True}, Marker.LINE_LIST, 1),
        ({"type": "line", "points": [[0, 0, 0], [1, 0, 0], [1, 1, 0]], "radius": 0.02, "closed": True,
          "end_head": True}, Marker.LINE_STRIP, 1),
    ]  # fmt: skip


class Collected:
    """The replies a translator sends, by channel."""

    def __init__(self) -> None:
        self.sent: list[tuple[str, bytes]] = []

    def __call__(self, channel: str, data: bytes) -> None:
        self.sent.append((channel, data))


def serve(server: TreeViewerServer, data: bytes, channel: str = REQUEST) -> tuple[list[Any], Any]:
    """One request through the server: (the markers it publishes, or None) and the raised error."""
    try:
        outputs = server.translate(Received(channel, data))
    except BridgeError as error:
        return [], error
    return [deserialize_message(payload, MarkerArray) for _, payload in outputs], None


def test_every_geometry_type_and_command(lcmgen: dict[str, type], tmp_path: Path) -> None:
    client = SpecClient(lcmgen)
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    replies = Collected()
    server = TreeViewerServer({"mesh_roots": [str(tmp_path)]}, reply=replies)
    for index, (geometry, marker_type, count) in enumerate(every_geometry(str(mesh))):
        path = ["robot", f"part{index}", "shape"]
        (array,), error = serve(
            server, client.wrap(request(setgeometry=[{"path": path, "geometry": geometry}]))
        )
        assert error is None
        channel, reply = replies.sent[-1]
        assert channel == RESPONSE and client.read(reply) == {"timestamp": 1_700_000_000_000_000, "status": 0}
        assert array.markers[0].action == Marker.DELETEALL  # geometry changed: RViz starts over
        ours = [m for m in array.markers if m.ns == f"robot/part{index}"]
        assert [m.type for m in ours][:1] == [marker_type] and len(ours) == count, geometry["type"]
    markers = {m.ns: m for m in array.markers[1:]}
    cloud = markers["robot/part7"]
    assert [[p.x, p.y, p.z] for p in cloud.points] == [[0, 0, 0], [1, 1, 1]]
    assert [[c.r, c.g, c.b] for c in cloud.colors] == [[1, 0, 0], [0, 0, 1]]
    lidar = np.array([[p.x, p.y, p.z] for p in markers["robot/part8"].points])
    np.testing.assert_allclose(lidar, [[1, 0, 0], [0, 2, 0], [-3, 0, 0]], atol=1e-12)
    triad = markers["robot/part9"]
    assert len(triad.points) == 6 and triad.points[1].x == 0.5 and [c.g for c in triad.colors][2:4] == [1, 1]
    line = markers["robot/part10"]
    assert [p.x for p in line.points] == [0, 1, 1, 0]  # closed: back to the first point
    assert markers["robot/part5"].mesh_resource == f"file://{mesh}" and markers["robot/part5"].scale.x == 2
    # settransform moves a whole subtree; the reply says OK; delete removes it.
    move = request(
        settransform=[
            {"path": ["robot"], "transform": {"translation": [0, 0, 1], "quaternion": [1, 0, 0, 0]}}
        ]
    )
    (array,), _ = serve(server, client.wrap(move))
    assert client.read(replies.sent[-1][1])["status"] == 0
    assert array.markers[0].action == Marker.ADD  # only poses changed: no DELETEALL
    assert {m.ns: m.pose.position.z for m in array.markers}["robot/part0"] == 1.0
    (array,), _ = serve(server, client.wrap(request(delete=[{"path": ["robot", "part0"]}])))
    assert (
        "robot/part0" not in {m.ns for m in array.markers}
        and len(server.trees["spec client"].scene().links) == 10
    )


def test_missing_paths_are_reported(lcmgen: dict[str, type]) -> None:
    client = SpecClient(lcmgen)
    replies = Collected()
    server = TreeViewerServer({}, reply=replies)
    move = request(settransform=[{"path": ["nothing", "here"], "transform": {}}])
    serve(server, client.wrap(move))
    assert client.read(replies.sent[-1][1])["missing_paths"] == [["nothing", "here"]]
    assert client.read(replies.sent[-1][1])["status"] == 1


@pytest.mark.parametrize(
    ("payload", "format_name", "major", "status", "text"),
    [
        (request(), "treeviewer_yaml", 1, -1, "unknown format 'treeviewer_yaml'"),
        (request(), "treeviewer_json", 2, -2, "unknown version 2.0"),
        (b'{"setgeometry": [', "treeviewer_json", 1, -3, "not JSON"),
        ({"setgeometry": [{"geometry": {"type": "box", "lengths": [1, 1, 1]}}]}, "treeviewer_json", 1, -3,
         "setgeometry[0].path must be a list of strings"),
        ({"settransform": "everything"}, "treeviewer_json", 1, -3, "settransform is not a list"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "box", "lengths": ["x", 1, 1]}}]}, "treeviewer_json",
         1, -3, "lengths must be a number"),
        ({"explode": [{"path": ["a"]}]}, "treeviewer_json", 1, -4, "unknown command 'explode'"),
    ],
)  # fmt: skip
def test_error_replies(
    lcmgen: dict[str, type], payload: Any, format_name: str, major: int, status: int, text: str
) -> None:
    client = SpecClient(lcmgen)
    replies = Collected()
    server = TreeViewerServer({}, reply=replies)
    markers, error = serve(server, client.wrap(payload, format_name, major))
    assert markers == [] and error is not None  # counted by the router as an error
    ((channel, reply),) = replies.sent
    answer = client.read(reply)
    assert channel == RESPONSE and answer["status"] == status and text in answer["error"], answer
    if status == -1:
        assert answer["supported_formats"] == {"treeviewer_json": [[1, 0]]}


def fuzzed_requests(count: int, seed: int = 7) -> list[bytes]:
    """Requests that are mostly almost right: valid ones mutated in their JSON and in their bytes."""
    rng = random.Random(seed)
    geometries = every_geometry("/nowhere/m.obj")
    odd_values: list[Any] = [
        None,
        True,
        -1,
        1e308,
        float("nan"),
        "x",
        [],
        {},
        [1, 2],
        [[1, 2, 3]] * 2,
        {"a": 1},
    ]
    out = []
    for _ in range(count):
        geometry = dict(rng.choice(geometries)[0])
        if rng.random() < 0.6:
            key = rng.choice([*geometry, "type", "color", "transform", "points", "radius"])
            geometry[key] = rng.choice(odd_values)
        command = rng.choice(["setgeometry", "settransform", "delete", "bogus"])
        body: dict[str, Any] = {"path": rng.choice([["a"], ["a", "b"], [], "a", [1], None])}
        if command == "setgeometry":
            body[rng.choice(["geometry", "geometries"])] = geometry if rng.random() < 0.8 else [geometry]
        elif command == "settransform":
            body["transform"] = rng.choice(
                [{}, {"translation": [1, 2, 3]}, {"quaternion": [0, 0, 0, 0]}, "x"]
            )
        payload: Any = {command: [body] if rng.random() < 0.9 else body}
        if rng.random() < 0.2:
            payload["timestamp"] = rng.choice(odd_values)
        data = json.dumps(payload, allow_nan=True).encode()
        if rng.random() < 0.3:  # damage the JSON text
            cut = rng.randrange(len(data))
            data = data[:cut] + bytes([rng.randrange(256)]) + data[cut + 1 :]
        message = VIEWER2_COMMS.message_class(
            utime=0, format=rng.choice(["treeviewer_json"] * 9 + ["json"]),
            format_version_major=rng.choice([1] * 9 + [0]), format_version_minor=0, num_bytes=len(data), data=data,
        )  # fmt: skip
        raw = VIEWER2_COMMS.encode(message)
        if rng.random() < 0.1:  # damage the envelope itself
            raw = raw[: rng.randrange(len(raw))]
        out.append(raw)
    return out


@pytest.mark.slow
def test_100000_fuzzed_requests_get_a_reply_each_and_never_crash(tmp_path: Path) -> None:
    replies = Collected()
    server = TreeViewerServer({"mesh_roots": [str(tmp_path)]}, reply=replies)
    statuses: dict[int, int] = {}
    for data in fuzzed_requests(100_000):
        before = len(replies.sent)
        with contextlib.suppress(BridgeError):  # a bad request: answered, and counted by the router
            server.translate(Received(REQUEST, data))
        assert len(replies.sent) == before + 1
        status = envelope.decode(replies.sent[-1][1])["status"]
        statuses[status] = statuses.get(status, 0) + 1
    assert set(statuses) <= {0, 1, -1, -2, -3, -4} and len(statuses) >= 5, statuses
    assert statuses.get(0, 0) > 1000 and statuses.get(-3, 0) > 1000


# --- the client side ----------------------------------------------------------------------------


def test_client_resends_on_missing_paths_and_the_viewer_tree_is_complete() -> None:
    scene = small_scene()
    client = DrakeToTreeViewer({})
    to_client = Collected()
    viewer = TreeViewerServer({}, reply=to_client)

    def deliver(outputs: list[tuple[int, bytes]]) -> None:
        for _, data in outputs:
            viewer.translate(Received("DIRECTOR_TREE_VIEWER_REQUEST_<drake>", data))

    deliver(client.translate(Received("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode())))
    deliver(client.translate(Received("DRAKE_VIEWER_DRAW", draw_of(scene, 1.0))))
    assert len(viewer.trees["drake"].scene().links) == 2
    # The viewer restarts and forgets its tree; the next draw's settransforms miss their paths.
    viewer.trees.clear()
    deliver(client.translate(Received("DRAKE_VIEWER_DRAW", draw_of(scene, 2.0))))
    answer = envelope.decode(to_client.sent[-1][1])
    assert answer["status"] == envelope.MISSING_PATHS and len(answer["missing_paths"]) == 2
    deliver(client.translate(Received("DIRECTOR_TREE_VIEWER_RESPONSE_<drake>", to_client.sent[-1][1])))
    assert envelope.decode(to_client.sent[-1][1])["status"] == envelope.OK
    rebuilt = viewer.trees["drake"].scene()
    sent = decode_load(load_from_scene(scene).encode())  # as the client saw it: float32 on LCM
    assert {link.name: link for link in rebuilt.links} == {link.name: link for link in sent.links}
    assert rebuilt.poses is not None and rebuilt.poses.pose_of("plant::robot::tip") == Pose((0.5, 0.0, 2.0))


def test_client_stops_when_the_viewer_does_not_speak_its_format() -> None:
    client = DrakeToTreeViewer({})
    refusal = envelope.encode(
        {"status": envelope.ERROR_UNKNOWN_FORMAT_VERSION, "error": "unknown version 1.0"}
    )
    with pytest.raises(BridgeError, match="the viewer refused treeviewer_json 1.0 .status -2"):
        client.translate(Received("DIRECTOR_TREE_VIEWER_RESPONSE_<drake>", refusal))
    with pytest.raises(BridgeError, match="no longer sending"):
        client.translate(Received("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(small_scene()).encode()))


# --- end to end: the bridge as a process, a client over LCM, markers in rclpy -------------------------

SERVER = """\
routes:
  - name: tree_viewer
    source: {{transport: lcm, name: "DIRECTOR_TREE_VIEWER_REQUEST_<([^<>]*)>"}}
    translator: tree_viewer_server
    destination: {{transport: ros, name: "/director/{{1:topic}}/markers"}}
    qos: {{depth: 1000}}
    rate: {{policy: all}}
    options: {{mesh_roots: ["{root}"]}}
"""


@pytest.mark.slow
def test_a_spec_client_drives_the_bridge_over_lcm(lcmgen: dict[str, type], tmp_path: Path) -> None:
    client = SpecClient(lcmgen)
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    url = lcm_url(5)
    probe = RosProbe()
    received = probe.subscribe("/director/spec_client/markers", "visualization_msgs/msg/MarkerArray", 1000)
    bus = LcmBus(url)
    replies: list[dict[str, Any]] = []
    bus.subscribe(RESPONSE, lambda _, data, __: replies.append(client.read(data)))
    bus.start()
    bridge = BridgeProcess("-c", str(write_config(tmp_path, SERVER.format(root=tmp_path))), "--lcm-url", url)
    try:
        bridge.wait_for_line(" running (")
        hello = client.wrap(request(settransform=[{"path": ["probe"], "transform": {}}]))
        deadline = time.monotonic() + 60
        while not received and time.monotonic() < deadline:  # until DDS has matched the probe
            bus.publish(REQUEST, hello)
            time.sleep(0.2)
        sent = len(replies)
        geometries = every_geometry(str(mesh))
        for index, (geometry, _, _) in enumerate(geometries):
            bus.publish(
                REQUEST,
                client.wrap(request(setgeometry=[{"path": ["r", f"g{index}", "s"], "geometry": geometry}])),
            )
        bus.publish(REQUEST, client.wrap({"explode": []}))
        assert probe.wait_for(lambda: len(replies) >= sent + len(geometries) + 1)
        assert probe.wait_for(lambda: any(len(a.markers) >= len(geometries) + 2 for a in received))
    finally:
        assert bridge.stop() == 0
        bus.close()
        probe.close()
    assert [r["status"] for r in replies[sent:]] == [0] * len(geometries) + [-4]
    last = max(received, key=lambda array: len(array.markers))
    types = sorted({m.type for m in last.markers if m.ns.startswith("r/")})
    assert types == sorted({Marker.CUBE, Marker.SPHERE, Marker.CYLINDER, Marker.MESH_RESOURCE, Marker.TRIANGLE_LIST,
                            Marker.POINTS, Marker.LINE_LIST, Marker.LINE_STRIP})  # fmt: skip


BOTH_SIDES = """\
routes:
  - name: to_director
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)|DIRECTOR_TREE_VIEWER_RESPONSE_<drake>"}
    translator: drake_to_tree_viewer
    destination: {transport: lcm, name: "DIRECTOR_TREE_VIEWER_REQUEST_<drake>"}
    rate: {policy: all}
  - name: as_director
    source: {transport: lcm, name: "DIRECTOR_TREE_VIEWER_REQUEST_<([^<>]*)>"}
    translator: tree_viewer_server
    destination: {transport: ros, name: "/director/{1:topic}/markers"}
    rate: {policy: all}
    qos: {depth: 100}
    options: {mesh_roots: ["DEMO_MESHES"]}
""".replace("DEMO_MESHES", str(DEMO_MESH.parent))


@pytest.mark.slow
def test_client_and_server_routes_carry_the_demo_scene_through_the_tree_viewer(tmp_path: Path) -> None:
    """Demo scene -> client route -> tree viewer requests on LCM -> server route -> MarkerArray."""
    url = lcm_url(6)
    probe = RosProbe()
    received = probe.subscribe("/director/drake/markers", "visualization_msgs/msg/MarkerArray", 100)
    stats = tmp_path / "stats.json"
    bridge = BridgeProcess("-c", str(write_config(tmp_path, BOTH_SIDES)), "--lcm-url", url, "--demo",
                           "--stats-json", str(stats))  # fmt: skip
    try:
        bridge.wait_for_line(" running (")
        assert probe.wait_for(lambda: any(len({m.ns for m in a.markers}) >= 8 for a in received), timeout=30)
    finally:
        assert bridge.stop() == 0
        probe.close()
    namespaces = {m.ns for a in received for m in a.markers}
    assert {"demo::shapes::box_0", "demo::shapes::trianglemesh_6"} <= {
        ns.replace("/", "::") for ns in namespaces
    }
    routes = json.loads(stats.read_text())["routes"]
    assert routes["to_director"]["messages_out"] > 0 and routes["as_director"]["messages_out"] > 0
