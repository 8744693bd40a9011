"""Director tree viewer JSON: every Drake shape out, requests back in, and what is refused."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings

from bridge.errors import DecodeError, SceneError
from bridge.formats import tree_viewer as tv
from bridge.lcmcodec import VIEWER2_COMMS
from bridge.scene import Box, Geometry, Link, Pose, Scene
from tests.conftest import Capture
from tests.formats import oracle
from tests.formats.oracle import close
from tests.strategies import scenes

ROLES = ["ILLUSTRATION", "PROXIMITY"]


def to_decimals(values: Any) -> list[float]:
    """Numbers as a settransform writes them: to `tv.DECIMALS` decimals, written out by hand here."""
    return [round(float(value) * 10**tv.DECIMALS) / 10**tv.DECIMALS for value in values]


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_becomes_setgeometry(drake_capture: dict[str, Capture], role: str) -> None:
    capture = drake_capture[role]
    delete, load = (tv.decode(tv.encode(request)) for request in tv.load_requests(capture.scene))
    assert delete["delete"] == [{"path": ["drake"]}] and delete["setgeometry"] == []
    commands = iter(load["setgeometry"])
    for raw_link in capture.load.link:
        for index, geometry in enumerate(raw_link.geom):
            command = next(commands)
            assert command["path"] == ["drake", str(raw_link.robot_num), raw_link.name, str(index)]
            shape, data = command["geometry"], geometry.float_data
            assert close(shape["transform"]["quaternion"], geometry.quaternion)  # w first, as Drake's
            assert close(shape["transform"]["translation"], geometry.position)
            assert close(shape["color"], geometry.color)
            kind = oracle.mesh_kind(geometry)
            expected: dict[str, Any] = {
                oracle.BOX: {"type": "box", "lengths": data},
                oracle.SPHERE: {"type": "sphere", "radius": data[0] if data else None},
                oracle.CYLINDER: {"type": "cylinder", "radius": data[0], "length": data[-1]},
                oracle.CAPSULE: {"type": "capsule", "radius": data[0], "length": data[-1]},
                oracle.ELLIPSOID: {"type": "ellipsoid", "radii": data},
            }.get(geometry.type, {})
            if kind == "file":
                expected = {"type": "mesh_file", "filename": geometry.string_data, "scale": data}
            elif kind == "array":
                vertices, triangles = oracle.mesh_array(geometry)
                expected = {"type": "mesh_data", "vertices": vertices.tolist(), "faces": triangles.tolist()}
            elif kind == "memory":  # read with trimesh: the tetrahedron, scaled
                expected = {"type": "mesh_data", "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]}
            assert shape["type"] == expected.pop("type")
            for key, value in expected.items():
                assert close(shape[key], value) if key != "filename" else shape[key] == value, key
    assert next(commands, None) is None
    settransform = {tuple(c["path"]): c["transform"] for c in load["settransform"]}
    for index, name in enumerate(capture.poses.names):
        transform = settransform[("drake", str(capture.poses.robot_nums[index]), name)]
        assert transform["quaternion"] == to_decimals(capture.poses.quaternions_wxyz[index])
        assert transform["translation"] == to_decimals(capture.poses.positions[index])


@pytest.mark.parametrize("role", ROLES)
def test_drake_scene_reads_back_from_the_tree(
    drake_capture: dict[str, Capture], drake_mesh_dir: Path, role: str
) -> None:
    capture = drake_capture[role]
    back = tv.scene_from_requests(tv.load_requests(capture.scene), mesh_roots=[drake_mesh_dir])
    original = {link.name: link for link in capture.scene.links}
    assert [link.name for link in back.links] == list(original)
    for link in back.links:
        assert link.robot_num == original[link.name].robot_num
        for ours, theirs in zip(link.geometries, original[link.name].geometries, strict=True):
            if type(theirs.shape).__name__ != "InMemoryMesh":  # sent as mesh_data: no way back
                assert ours.shape == theirs.shape
            assert ours.pose == theirs.pose and ours.color == theirs.color
    drawn = [name for name in capture.poses.names]
    assert back.poses is not None
    for name in drawn:
        ours_pose, theirs_pose = back.poses.pose_of(name), capture.poses.pose(capture.poses.names.index(name))
        assert ours_pose is not None
        assert ours_pose.position == tuple(to_decimals(theirs_pose.position))
        assert ours_pose.quaternion_wxyz == tuple(to_decimals(theirs_pose.quaternion_wxyz))


@settings(max_examples=60, deadline=None)
@given(scenes())
def test_scene_to_tree_json_to_scene_round_trips(scene: Scene) -> None:
    requests = [json.loads(json.dumps(request)) for request in tv.load_requests(scene)]
    back = tv.scene_from_requests(requests, mesh_roots=["/meshes"])
    with_geometry = tuple(link for link in scene.links if link.geometries)

    def order(links: tuple[Link, ...]) -> list[Link]:
        return sorted(links, key=lambda link: (link.robot_num, link.name))

    assert order(back.links) == order(with_geometry)  # a link with no geometry has no node


def test_draw_moves_links_and_missing_paths_are_reported() -> None:
    scene = Scene((Link("plant::a", 2, (Geometry(Box((1.0, 1.0, 1.0)), Pose((0.0, 0.0, 1.0))),)),))
    state = tv.TreeState()
    for request in tv.load_requests(scene):
        assert state.apply(request)["status"] == tv.OK
    move = {"timestamp": 7000, "settransform": [
        {"path": ["drake", "2", "plant::a"], "transform": {"translation": [1, 2, 3], "quaternion": [0, 1, 0, 0]}},
        {"path": ["drake", "9", "ghost"], "transform": {}},
    ]}  # fmt: skip
    response = state.apply(move)
    assert response == {
        "timestamp": 7000,
        "status": tv.MISSING_PATHS,
        "missing_paths": [["drake", "9", "ghost"]],
    }
    moved = state.scene()
    assert moved.poses is not None and moved.poses.pose_of("plant::a") == Pose(
        (1.0, 2.0, 3.0), (0.0, 1.0, 0.0, 0.0)
    )
    assert moved.links[0].geometries[0].pose == Pose((0.0, 0.0, 1.0))  # in the link frame still
    state.apply({"delete": [{"path": ["drake"]}]})
    assert state.scene().links == ()


def test_director_clients_geometries_list_and_utime_are_accepted() -> None:
    state = tv.TreeState(mesh_roots=["/"])
    request = {"utime": 5, "setgeometry": [{"path": ["robot1", "link1"], "geometries": [
        {"type": "box", "lengths": [1, 0.5, 2], "color": [1, 0, 0, 0.5]},
        {"type": "mesh_file", "filename": "/m.obj", "scale": 2},
    ]}]}  # fmt: skip
    assert state.apply(request) == {"timestamp": 5, "status": tv.OK}
    (link,) = state.scene().links
    assert link.name == "robot1" and [type(g.shape).__name__ for g in link.geometries] == ["Box", "MeshFile"]
    assert link.geometries[1].shape.scale == (2.0, 2.0, 2.0)  # type: ignore[union-attr]


@pytest.mark.parametrize(
    ("command", "reason"),
    [
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "teapot"}}]}, "unknown geometry type 'teapot'"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "box", "lengths": [1]}}]}, "box needs 3 values"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "sphere", "radius": "big"}}]}, "must be a number"),
        ({"setgeometry": [{"path": "a", "geometry": {"type": "sphere", "radius": 1}}]}, "path must be a list"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "pointcloud"}}]}, "points must be a list"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "pointcloud", "points": [[0, 0, 0]],
                                                        "channels": {"rgb": []}}}]}, "one per point"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "line", "points": [[0, 0, 0]]}}]}, "2 or more"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "triad", "tube": "yes"}}]}, "true or false"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "planar_lidar", "ranges": [1]}}]}, "angle_start"),
        ({"settransform": [{"path": ["a"], "transform": {"quaternion": [0, 0, 0, 0]}}]}, "length 0 is not a rotation"),
        ({"settransform": [{"path": ["a"], "transform": {"translation": [1, None, 2]}}]}, "3 finite numbers"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "mesh_data", "vertices": [[0, 0, 0]],
                                                        "faces": [[0, 1, 2]]}}]}, "faces refer to a vertex"),
    ],
)  # fmt: skip
def test_bad_commands_raise_scene_errors(command: dict[str, Any], reason: str) -> None:
    state = tv.TreeState()
    with pytest.raises(SceneError, match=reason):
        state.apply(command)
    assert state.respond(command) == {"timestamp": 0, "status": tv.ERROR_HANDLING_REQUEST, "error": ANY_TEXT}


class _AnyText:
    def __eq__(self, other: object) -> bool:
        return isinstance(other, str) and len(other) > 10


ANY_TEXT: Any = _AnyText()


def test_unknown_command_is_4_and_leaves_the_tree_alone() -> None:
    state = tv.TreeState()
    request = {
        "setgeometry": [{"path": ["a"], "geometry": {"type": "sphere", "radius": 1}}],
        "frobnicate": [],
    }
    response = state.respond(request)
    assert response["status"] == tv.ERROR_UNKNOWN_REQUEST_TYPE and "frobnicate" in response["error"]
    bad_later = {"setgeometry": [{"path": ["a"], "geometry": {"type": "sphere", "radius": 1}},
                                 {"path": ["b"], "geometry": {"type": "sphere", "radius": -1 * float("inf")}}]}  # fmt: skip
    assert state.respond(bad_later)["status"] == tv.ERROR_HANDLING_REQUEST
    assert state.scene().links == ()  # checked as a whole: nothing of either request was applied


def test_mesh_files_only_below_the_configured_roots(tmp_path: Path) -> None:
    inside = tmp_path / "meshes" / "a.obj"
    state = tv.TreeState(mesh_roots=[tmp_path / "meshes"])
    ok = {"setgeometry": [{"path": ["a"], "geometry": {"type": "mesh_file", "filename": str(inside)}}]}
    assert state.respond(ok)["status"] == tv.OK
    for path in ("/etc/passwd", str(tmp_path / "meshes" / ".." / "secret.obj")):
        request = {"setgeometry": [{"path": ["b"], "geometry": {"type": "mesh_file", "filename": path}}]}
        response = state.respond(request)
        assert (
            response["status"] == tv.ERROR_HANDLING_REQUEST
            and "outside the allowed folders" in response["error"]
        )


def envelope(format_name: str = tv.FORMAT, major: int = 1, data: bytes = b"{}") -> bytes:
    return VIEWER2_COMMS.encode(
        VIEWER2_COMMS.message_class(
            utime=1, format=format_name, format_version_major=major, format_version_minor=0,
            num_bytes=len(data), data=data,
        )
    )  # fmt: skip


@pytest.mark.parametrize(
    ("data", "status", "reason"),
    [
        (envelope("msgpack"), tv.ERROR_UNKNOWN_FORMAT, "unknown format 'msgpack'"),
        (envelope(major=2), tv.ERROR_UNKNOWN_FORMAT_VERSION, "unknown version 2.0"),
        (envelope(data=b'{"setgeometry": ['), tv.ERROR_HANDLING_REQUEST, "not JSON"),
        (envelope(data=b"[1, 2]"), tv.ERROR_HANDLING_REQUEST, "not an object"),
    ],
)
def test_bad_envelopes_carry_the_response_status(data: bytes, status: int, reason: str) -> None:
    with pytest.raises(tv.RequestRejected, match=reason) as caught:
        tv.decode(data)
    assert caught.value.status == status


def test_truncated_envelope_is_a_decode_error() -> None:
    with pytest.raises(DecodeError, match="robotlocomotion.viewer2_comms_t"):
        tv.decode(envelope()[:-1])
    assert tv.request_channel("abc") == "DIRECTOR_TREE_VIEWER_REQUEST_<abc>"
