"""ign/gz `Model` / `Model_V`, read back with protoc's classes for Debian's ign-msgs 8 files."""

from __future__ import annotations

from types import ModuleType

import numpy as np
import pytest
from hypothesis import given, settings

from tests.conftest import Capture
from tests.formats import oracle
from tests.formats.ign.oracle import pose_v, xyz
from tests.formats.oracle import close
from tests.strategies import scenes
from viewer_bridge.errors import DecodeError, SceneError
from viewer_bridge.formats.ign.model import model, model_v, scene_from_model
from viewer_bridge.formats.ign.poses import poses_from_pose_v
from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.model.scene import Box, Geometry, Link, LinkPoses, Pose, Scene

ROLES = ["ILLUSTRATION", "PROXIMITY"]


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_in_a_model_read_by_debians_protos(
    drake_capture: dict[str, Capture], debian_ign_msgs: ModuleType, role: str
) -> None:
    capture = drake_capture[role]
    data = model_v(capture.scene).SerializeToString()
    theirs = debian_ign_msgs.Model_V.FromString(data)
    links = [link for model in theirs.models for link in model.link]
    assert [link.name for link in links] == [link.name for link in capture.load.link]
    Type = debian_ign_msgs.Geometry
    for link, raw_link in zip(links, capture.load.link, strict=True):
        assert [(m.id, raw_link.robot_num) for m in theirs.models if link in m.link][0][
            0
        ] == raw_link.robot_num
        link_pose = capture.scene.poses.pose_of(raw_link.name) or Pose()
        assert close(xyz(link.pose.position), link_pose.position)
        for visual, geometry in zip(link.visual, raw_link.geom, strict=True):
            assert visual.parent_name == raw_link.name
            q = visual.pose.orientation
            assert close([q.x, q.y, q.z, q.w], oracle.xyzw(geometry))  # index 0 of Drake's is w
            assert close(xyz(visual.pose.position), geometry.position)
            diffuse = visual.material.diffuse
            assert close([diffuse.r, diffuse.g, diffuse.b, diffuse.a], geometry.color)
            data, shape = geometry.float_data, visual.geometry
            kind = oracle.mesh_kind(geometry)
            if geometry.type == oracle.BOX:
                assert shape.type == Type.BOX and close(xyz(shape.box.size), data)
            elif geometry.type == oracle.SPHERE:
                assert shape.type == Type.SPHERE and close(shape.sphere.radius, data[0])
            elif geometry.type == oracle.CYLINDER:
                assert shape.type == Type.CYLINDER and close(
                    [shape.cylinder.radius, shape.cylinder.length], data
                )
            elif geometry.type == oracle.CAPSULE:
                assert shape.type == Type.CAPSULE and close(
                    [shape.capsule.radius, shape.capsule.length], data
                )
            elif geometry.type == oracle.ELLIPSOID:
                assert shape.type == Type.ELLIPSOID and close(xyz(shape.ellipsoid.radii), data)
            elif kind == "file":
                assert shape.type == Type.MESH and shape.mesh.filename == geometry.string_data
                assert close(xyz(shape.mesh.scale), data)
            else:
                assert shape.type == Type.MESH and shape.mesh.filename.startswith("data:model/obj")
    assert scene_from_model(MESSAGES.parse("Model_V", theirs.SerializeToString())) == Scene(
        capture.scene.links
    )


def test_debians_messages_read_by_ours(debian_ign_msgs: ModuleType) -> None:
    theirs = debian_ign_msgs.Model(name="m")
    link = theirs.link.add(name="l")
    visual = link.visual.add(name="v")
    visual.geometry.type = debian_ign_msgs.Geometry.CYLINDER
    visual.geometry.cylinder.radius, visual.geometry.cylinder.length = 0.5, 2.0
    visual.pose.orientation.w = 1.0
    visual.material.diffuse.r = 1.0
    visual.transparency = 0.25  # a field we do not declare: skipped
    scene = scene_from_model(MESSAGES.parse("Model", theirs.SerializeToString()))
    (geometry,) = scene.links[0].geometries
    assert geometry.shape.__class__.__name__ == "Cylinder" and (
        geometry.shape.radius,
        geometry.shape.length,
    ) == (0.5, 2.0)
    assert geometry.color == (1.0, 0.0, 0.0, 0.0)


@settings(max_examples=60, deadline=None)
@given(scenes())
def test_load_to_model_to_load_round_trips(scene: Scene) -> None:
    for build in (model_v, model):
        message = build(scene)
        name = type(message).DESCRIPTOR.name
        back = scene_from_model(MESSAGES.parse(name, message.SerializeToString()))
        assert _rounded(back) == _rounded(scene)


def _rounded(scene: Scene) -> Scene:
    """Colours travel as float32, as Drake's do: compare them at that precision."""
    links = []
    for link in scene.links:
        geometries = tuple(
            Geometry(g.shape, g.pose, tuple(np.float32(g.color).tolist()))
            for g in link.geometries  # type: ignore[arg-type]
        )
        links.append(Link(link.name, link.robot_num, geometries))
    return Scene(tuple(sorted(links, key=lambda link: (link.robot_num, link.name))))


def test_bad_models_raise_scene_errors() -> None:
    message = model(Scene((Link("l", 0, (Geometry(Box((1.0, 1.0, 1.0))),)),)))
    visual = message.link[0].visual[0]
    visual.geometry.type = 5  # HEIGHTMAP: no scene shape
    with pytest.raises(SceneError, match="link 'l' visual 0: Geometry type HEIGHTMAP has no scene shape"):
        scene_from_model(message)
    visual.geometry.type = 0
    visual.geometry.box.size.y = float("inf")
    with pytest.raises(SceneError, match="box.size must be finite, got inf"):
        scene_from_model(message)
    visual.geometry.box.size.y = 1.0
    visual.pose.orientation.w = float("nan")
    with pytest.raises(SceneError, match="quaternion of length nan"):
        scene_from_model(message)
    visual.pose.orientation.w = 1.0
    visual.geometry.type = 6
    visual.geometry.mesh.filename = "data:model/obj;base64,!!!"
    with pytest.raises(SceneError, match="not base64"):
        scene_from_model(message)
    with pytest.raises(DecodeError, match="gz.msgs.Model"):
        MESSAGES.parse("Model", b"\xff\xff\xff")
    poses = pose_v(LinkPoses(0, ("a",), np.zeros(1, np.int32), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]])))
    poses.pose[0].position.x = float("inf")
    with pytest.raises(SceneError, match=r"pose\[0\].position is not finite"):
        poses_from_pose_v(poses)
