"""Tree viewer requests applied to a tree: Drake's scene read back, draws, MISSING_PATHS, Director's
own requests, and a request that is refused as a whole."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings

from tests.conftest import Capture
from tests.formats.tree_viewer.oracle import to_decimals
from tests.strategies import scenes
from viewer_bridge.formats.tree_viewer.envelope import (
    ERROR_HANDLING_REQUEST,
    ERROR_UNKNOWN_REQUEST_TYPE,
    MISSING_PATHS,
    OK,
)
from viewer_bridge.formats.tree_viewer.requests import load_requests
from viewer_bridge.formats.tree_viewer.tree import TreeState, scene_from_requests
from viewer_bridge.model.scene import Box, Geometry, Link, Pose, Scene

ROLES = ["ILLUSTRATION", "PROXIMITY"]


@pytest.mark.parametrize("role", ROLES)
def test_drake_scene_reads_back_from_the_tree(
    drake_capture: dict[str, Capture], drake_mesh_dir: Path, role: str
) -> None:
    capture = drake_capture[role]
    back = scene_from_requests(load_requests(capture.scene), mesh_roots=[drake_mesh_dir])
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
    requests = [json.loads(json.dumps(request)) for request in load_requests(scene)]
    back = scene_from_requests(requests, mesh_roots=["/meshes"])
    with_geometry = tuple(link for link in scene.links if link.geometries)

    def order(links: tuple[Link, ...]) -> list[Link]:
        return sorted(links, key=lambda link: (link.robot_num, link.name))

    assert order(back.links) == order(with_geometry)  # a link with no geometry has no node


def test_draw_moves_links_and_missing_paths_are_reported() -> None:
    scene = Scene((Link("plant::a", 2, (Geometry(Box((1.0, 1.0, 1.0)), Pose((0.0, 0.0, 1.0))),)),))
    state = TreeState()
    for request in load_requests(scene):
        assert state.apply(request)["status"] == OK
    move = {"timestamp": 7000, "settransform": [
        {"path": ["drake", "2", "plant::a"], "transform": {"translation": [1, 2, 3], "quaternion": [0, 1, 0, 0]}},
        {"path": ["drake", "9", "ghost"], "transform": {}},
    ]}  # fmt: skip
    response = state.apply(move)
    assert response == {
        "timestamp": 7000,
        "status": MISSING_PATHS,
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
    state = TreeState(mesh_roots=["/"])
    request = {"utime": 5, "setgeometry": [{"path": ["robot1", "link1"], "geometries": [
        {"type": "box", "lengths": [1, 0.5, 2], "color": [1, 0, 0, 0.5]},
        {"type": "mesh_file", "filename": "/m.obj", "scale": 2},
    ]}]}  # fmt: skip
    assert state.apply(request) == {"timestamp": 5, "status": OK}
    (link,) = state.scene().links
    assert link.name == "robot1" and [type(g.shape).__name__ for g in link.geometries] == ["Box", "MeshFile"]
    assert link.geometries[1].shape.scale == (2.0, 2.0, 2.0)  # type: ignore[union-attr]


def test_unknown_command_is_4_and_leaves_the_tree_alone() -> None:
    state = TreeState()
    request = {
        "setgeometry": [{"path": ["a"], "geometry": {"type": "sphere", "radius": 1}}],
        "frobnicate": [],
    }
    response = state.respond(request)
    assert response["status"] == ERROR_UNKNOWN_REQUEST_TYPE and "frobnicate" in response["error"]
    bad_later = {"setgeometry": [{"path": ["a"], "geometry": {"type": "sphere", "radius": 1}},
                                 {"path": ["b"], "geometry": {"type": "sphere", "radius": -1 * float("inf")}}]}  # fmt: skip
    assert state.respond(bad_later)["status"] == ERROR_HANDLING_REQUEST
    assert state.scene().links == ()  # checked as a whole: nothing of either request was applied


def test_mesh_files_only_below_the_configured_roots(tmp_path: Path) -> None:
    inside = tmp_path / "meshes" / "a.obj"
    state = TreeState(mesh_roots=[tmp_path / "meshes"])
    ok = {"setgeometry": [{"path": ["a"], "geometry": {"type": "mesh_file", "filename": str(inside)}}]}
    assert state.respond(ok)["status"] == OK
    for path in ("/etc/passwd", str(tmp_path / "meshes" / ".." / "secret.obj")):
        request = {"setgeometry": [{"path": ["b"], "geometry": {"type": "mesh_file", "filename": path}}]}
        response = state.respond(request)
        assert (
            response["status"] == ERROR_HANDLING_REQUEST
            and "outside the allowed folders" in response["error"]
        )
