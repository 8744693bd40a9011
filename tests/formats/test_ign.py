"""ign/gz protobuf translators, read back with protoc's classes for Debian's ign-msgs 8 files."""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bridge.errors import DecodeError, SceneError
from bridge.formats import ign
from bridge.formats.drake import DrawDecoder, DrawEncoder
from bridge.mappings import tables
from bridge.scene import Box, Geometry, HalfSpace, Link, LinkPoses, Pose, Scene
from tests.conftest import Capture
from tests.formats import oracle
from tests.formats.oracle import close
from tests.strategies import link_poses, scenes

ROLES = ["ILLUSTRATION", "PROXIMITY"]


def xyz(vector: Any) -> list[float]:
    return [vector.x, vector.y, vector.z]


def test_geometry_type_codes_are_debians(debian_ign_msgs: ModuleType) -> None:
    table = tables("ign")["geometry"]
    assert dict(table.types) == dict(debian_ign_msgs.Geometry.Type.items())


def test_our_fields_are_debians_fields(debian_ign_msgs: ModuleType) -> None:
    """Every field we declare has the number and type Debian's .proto files give it."""
    for name, cls in ign.IGNITION.classes.items():
        if name == "PosesStamped":  # removed from the .proto files in 2017; Debian has none
            continue
        theirs = getattr(debian_ign_msgs, name).DESCRIPTOR
        assert theirs.full_name == f"ignition.msgs.{name}"
        for field in cls.DESCRIPTOR.fields:
            other = theirs.fields_by_name[field.name]
            assert (field.number, field.type, field.is_repeated) == (
                other.number,
                other.type,
                other.is_repeated,
            ), field.full_name


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_in_a_model_read_by_debians_protos(
    drake_capture: dict[str, Capture], debian_ign_msgs: ModuleType, role: str
) -> None:
    capture = drake_capture[role]
    data = ign.model_v(capture.scene).SerializeToString()
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
    assert ign.scene_from_model(ign.IGNITION.parse("Model_V", theirs.SerializeToString())) == Scene(
        capture.scene.links
    )


@pytest.mark.parametrize("role", ROLES)
def test_pose_v_read_by_debians_protos(
    drake_capture: dict[str, Capture], debian_ign_msgs: ModuleType, role: str
) -> None:
    poses = drake_capture[role].poses
    theirs = debian_ign_msgs.Pose_V.FromString(ign.pose_v(poses).SerializeToString())
    assert theirs.header.stamp.sec * 1000 + theirs.header.stamp.nsec // 1_000_000 == poses.timestamp_ms
    assert [pose.name for pose in theirs.pose] == list(poses.names)
    for pose, position, (w, x, y, z) in zip(
        theirs.pose, poses.positions, poses.quaternions_wxyz, strict=True
    ):
        assert xyz(pose.position) == position.tolist()
        assert [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w] == [
            x,
            y,
            z,
            w,
        ]
    robot_nums = dict(zip(poses.names, poses.robot_nums.tolist(), strict=True))
    assert ign.poses_from_pose_v(
        ign.IGNITION.parse("Pose_V", theirs.SerializeToString()), robot_nums
    ) == LinkPoses(poses.timestamp_ms, poses.names, poses.robot_nums, poses.positions, poses.quaternions_wxyz)


def test_debians_messages_read_by_ours(debian_ign_msgs: ModuleType) -> None:
    theirs = debian_ign_msgs.Model(name="m")
    link = theirs.link.add(name="l")
    visual = link.visual.add(name="v")
    visual.geometry.type = debian_ign_msgs.Geometry.CYLINDER
    visual.geometry.cylinder.radius, visual.geometry.cylinder.length = 0.5, 2.0
    visual.pose.orientation.w = 1.0
    visual.material.diffuse.r = 1.0
    visual.transparency = 0.25  # a field we do not declare: skipped
    scene = ign.scene_from_model(ign.IGNITION.parse("Model", theirs.SerializeToString()))
    (geometry,) = scene.links[0].geometries
    assert geometry.shape.__class__.__name__ == "Cylinder" and (
        geometry.shape.radius,
        geometry.shape.length,
    ) == (0.5, 2.0)
    assert geometry.color == (1.0, 0.0, 0.0, 0.0)


@settings(max_examples=60, deadline=None)
@given(scenes())
def test_load_to_model_to_load_round_trips(scene: Scene) -> None:
    for msgs, build in ((ign.IGNITION, ign.model_v), (ign.GZ, ign.model_v), (ign.IGNITION, ign.model)):
        message = build(scene, msgs=msgs)
        name = type(message).DESCRIPTOR.name
        back = ign.scene_from_model(msgs.parse(name, message.SerializeToString()))
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


@settings(max_examples=60, deadline=None)
@given(link_poses())
def test_draw_to_pose_v_to_draw_round_trips(poses: LinkPoses) -> None:
    robot_nums = dict(zip(poses.names, poses.robot_nums.tolist(), strict=True))
    for build in (ign.pose_v, ign.poses_stamped):
        message = build(poses, ign.GZ)
        back = ign.poses_from_pose_v(
            ign.GZ.parse(type(message).DESCRIPTOR.name, message.SerializeToString()), robot_nums
        )
        assert back.names == poses.names and back.timestamp_ms == poses.timestamp_ms
        np.testing.assert_array_equal(back.positions, poses.positions)
        np.testing.assert_allclose(back.quaternions_wxyz, poses.quaternions_wxyz, atol=1e-15)


def test_gz_and_ignition_packages() -> None:
    assert ign.GZ.Pose_V.DESCRIPTOR.full_name == "gz.msgs.Pose_V"
    assert ign.IGNITION.Model_V.DESCRIPTOR.full_name == "ignition.msgs.Model_V"
    stamped = ign.poses_stamped(
        LinkPoses(1500, ("a",), np.zeros(1, np.int32), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]))
    )
    assert (stamped.time.sec, stamped.time.nsec) == (1, 500_000_000)
    fields = {f.name: f.number for f in stamped.DESCRIPTOR.fields}
    assert fields == {"header": 1, "time": 2, "pose": 3}


def test_half_space_is_a_plane() -> None:
    scene = Scene((Link("world", 0, (Geometry(HalfSpace()),)),))
    visual = ign.model(scene).link[0].visual[0]
    assert visual.geometry.type == tables("ign")["geometry"].types["PLANE"]
    assert xyz(visual.geometry.plane.normal) == [0, 0, 1] and visual.geometry.plane.size.x == 50
    assert ign.scene_from_model(ign.model(scene)).links[0].geometries[0].shape == HalfSpace()


def test_bad_models_raise_scene_errors() -> None:
    message = ign.model(Scene((Link("l", 0, (Geometry(Box((1.0, 1.0, 1.0))),)),)))
    visual = message.link[0].visual[0]
    visual.geometry.type = 5  # HEIGHTMAP: no scene shape
    with pytest.raises(SceneError, match="link 'l' visual 0: Geometry type HEIGHTMAP has no scene shape"):
        ign.scene_from_model(message)
    visual.geometry.type = 0
    visual.geometry.box.size.y = float("inf")
    with pytest.raises(SceneError, match="box.size must be finite, got inf"):
        ign.scene_from_model(message)
    visual.geometry.box.size.y = 1.0
    visual.pose.orientation.w = float("nan")
    with pytest.raises(SceneError, match="quaternion of length nan"):
        ign.scene_from_model(message)
    visual.pose.orientation.w = 1.0
    visual.geometry.type = 6
    visual.geometry.mesh.filename = "data:model/obj;base64,!!!"
    with pytest.raises(SceneError, match="not base64"):
        ign.scene_from_model(message)
    with pytest.raises(DecodeError, match="ignition.msgs.Model"):
        ign.IGNITION.parse("Model", b"\xff\xff\xff")
    poses = ign.pose_v(
        LinkPoses(0, ("a",), np.zeros(1, np.int32), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]))
    )
    poses.pose[0].position.x = float("inf")
    with pytest.raises(SceneError, match=r"pose\[0\].position is not finite"):
        ign.poses_from_pose_v(poses)


@pytest.mark.parametrize("obj", ["v 1 2\n", "v 0 0 0\n\nf 1 2\n", "v 0 0 0\nf 1 1 9\n", "v nan 0 0\n"])
def test_mesh_array_objs_that_do_not_hold_together(obj: str) -> None:
    import base64

    message = ign.model(Scene((Link("l", 0, (Geometry(Box((1.0, 1.0, 1.0))),)),)))
    geometry = message.link[0].visual[0].geometry
    geometry.type = 6
    geometry.mesh.filename = "data:model/obj;base64," + base64.b64encode(obj.encode()).decode()
    with pytest.raises(SceneError, match="mesh array OBJ"):
        ign.scene_from_model(message)


def _oracle(poses: LinkPoses, message: str) -> bytes:
    """The protobuf-object path: the reference the template encoder must equal byte for byte."""
    build = ign.pose_v if message == "Pose_V" else ign.poses_stamped
    return bytes(build(poses).SerializeToString())


@settings(max_examples=80, deadline=None)
@given(st.lists(link_poses(max_links=5), min_size=1, max_size=4), st.sampled_from(["Pose_V", "PosesStamped"]))
def test_poses_encoder_writes_protobufs_bytes(frames: list[LinkPoses], message: str) -> None:
    """One encoder over several frames (names and zeros changing or not): protobuf's bytes each time."""
    encoder = ign.PosesEncoder(message)
    for poses in frames:
        assert encoder.encode(poses) == _oracle(poses, message)


def test_poses_encoder_follows_zeros_and_signs_from_frame_to_frame() -> None:
    """+0.0 is left out and -0.0 written, as protobuf does; a value reaching or leaving 0 changes
    the layout; a negative or zero time leaves fields out as protobuf does."""
    encoder = ign.PosesEncoder()
    names = ("plant::a", "plant::robot::b", "world_fixed")
    base = np.array([[0.5, -1.0, 2.0], [0.0, 0.0, 0.0], [1e-300, -0.0, 3.0]])
    quaternions = np.array([[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5], [0.0, -0.0, 1.0, 0.0]])
    for step, timestamp in enumerate([0, 1, 999, 1000, 1500, -1500, 2**40]):
        positions = base.copy()
        positions[0, 1] = 0.0 if step % 2 else -1.0  # a value reaching 0 and leaving it again
        poses = LinkPoses(timestamp, names, np.zeros(3, np.int32), positions, quaternions)
        assert encoder.encode(poses) == _oracle(poses, "Pose_V")
    assert encoder.encode(LinkPoses(5, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))) == (
        _oracle(LinkPoses(5, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4))), "Pose_V")
    )


@pytest.mark.parametrize("role", ROLES)
def test_poses_encoder_on_drakes_draws(
    drake_capture: dict[str, Capture], debian_ign_msgs: ModuleType, role: str
) -> None:
    """Drake's own draws, decoded on the fast path: protobuf's bytes, which Debian's protos read."""
    poses = DrawDecoder().decode(DrawEncoder().encode(drake_capture[role].poses))  # Drake's bytes
    assert poses.positions.dtype == np.float32  # the fast decoder's arrays, as the bridge has them
    encoded = ign.PosesEncoder().encode(poses)
    assert encoded == _oracle(poses, "Pose_V")
    theirs = debian_ign_msgs.Pose_V.FromString(encoded)
    assert [pose.name for pose in theirs.pose] == list(poses.names)
