"""The loads' fast paths against their references: the same bytes as the object paths."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message
from shape_msgs.msg import Mesh, SolidPrimitive

from bridge.demo import TETRAHEDRON_OBJ
from bridge.errors import SceneError
from bridge.formats import ign, ros
from bridge.lowering import _tessellated, triangle_mesh
from bridge.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    FileContents,
    Geometry,
    HalfSpace,
    InMemoryMesh,
    Link,
    LinkPoses,
    MeshFile,
    Pose,
    Scene,
    Sphere,
    TriangleMesh,
)
from tests.conftest import Capture
from tests.strategies import link_poses, poses, scenes


def every_kind(folder: Path) -> Scene:
    """Every shape a load can carry that the shape table writes, some repeated (cached meshes)."""
    obj = folder / "tetra.obj"
    obj.write_text(TETRAHEDRON_OBJ)
    tilted = Pose((0.1, -0.2, 0.3), (0.5, 0.5, 0.5, 0.5))
    shapes = [
        Box((0.1, 0.2, 0.3)), Sphere(0.05), Cylinder(0.04, 0.3), Capsule(0.03, 0.2), Capsule(0.03, 0.2),
        Ellipsoid((0.1, 0.2, 0.3)), Ellipsoid((0.1, 0.2, 0.3)), HalfSpace(), MeshFile(str(obj), (1.0, 2.0, 3.0)),
        MeshFile(str(obj)), InMemoryMesh(FileContents(TETRAHEDRON_OBJ.encode(), ".obj", "t.obj"), {}, (2.0, 2.0, 2.0)),
        TriangleMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])),
    ]  # fmt: skip
    links = tuple(
        Link(f"plant::m::link_{index}", index % 3, (Geometry(shape, tilted, (0.1, 0.2, 0.3, 1.0)),))
        for index, shape in enumerate(shapes)
    )
    return Scene(links)


def reference_shapes(scene: Scene) -> list[tuple[str, bytes]]:
    """The object path: rosbags messages, serialised by rosbags."""
    return [(posed.typename, ros.to_cdr(posed.shape)) for posed in ros.shapes(scene)]


def test_shape_bytes_equal_the_object_path_for_every_kind(tmp_path: Path) -> None:
    scene = every_kind(tmp_path)
    fast = ros.shapes_cdr(scene)
    assert fast == reference_shapes(scene)
    # and rclpy reads them: the real peer
    kinds = {ros.SOLID_PRIMITIVE: SolidPrimitive, ros.MESH: Mesh}
    read = [deserialize_message(data, kinds[name]) for name, data in fast if name in kinds]
    assert [list(message.dimensions) for message in read[:2]] == [[0.1, 0.2, 0.3], [0.05]]
    assert any(isinstance(message, Mesh) and len(message.triangles) == 1 for message in read)


@settings(max_examples=100, deadline=None)
@given(scenes())
def test_shape_bytes_equal_the_object_path_for_random_scenes(scene: Scene) -> None:
    try:
        expected = reference_shapes(scene)
    except SceneError:  # a mesh file that does not exist: the fast path refuses it as well
        with pytest.raises(SceneError):
            ros.shapes_cdr(scene)
        return
    assert ros.shapes_cdr(scene) == expected


def test_shape_bytes_of_real_drake_loads(drake_capture: dict[str, Capture]) -> None:
    for capture in drake_capture.values():
        assert ros.shapes_cdr(capture.scene) == reference_shapes(capture.scene)


def test_tessellations_are_cached_read_only_and_equal_fresh_ones() -> None:
    primitives = (Box((1.0, 2.0, 3.0)), Sphere(0.5), Cylinder(0.1, 0.4), Capsule(0.1, 0.4), Ellipsoid((1.0, 2.0, 3.0)))
    for shape in (*primitives, HalfSpace()):
        cached = triangle_mesh(shape)
        assert triangle_mesh(shape) is cached
        assert cached == _tessellated(shape)
        with pytest.raises(ValueError, match="read-only"):
            cached.vertices[0, 0] = 1.0


def test_every_load_target_writes_the_recorded_bytes() -> None:
    """The load paths' bytes for fixed scenes, against digests recorded before they were optimised.

    The six `*_posed/marker_array` and `marker_stream_load` entries were recorded again once
    world-frame marker poses were composed by `scene.PartsOnLinks` (issue 15): the same poses,
    different last bits (`tests/test_scene.py` checks it against `Pose.compose`). The three
    `*_posed/tree_viewer` entries were recorded again once settransform numbers were written to
    `tv.DECIMALS` decimals (issue 15; `test_tree_viewer_fast.py` checks the rounding). The six
    `every_kind*/foxglove` and `every_kind*/ign_model*` entries, "refused" before, were recorded
    again once a geometry a target cannot write was skipped alone (issue 26): the point cloud is
    left out and the rest written (`tests/test_skipped.py` checks those bytes against the scene
    without the point cloud).
    """
    import json

    from tests.formats import load_outputs

    load_outputs.FOLDER.mkdir(exist_ok=True)
    recorded = json.loads((Path(__file__).parent / "load_digests.json").read_text())
    assert load_outputs.digests(load_outputs.FOLDER) == recorded


@settings(max_examples=150, deadline=None)
@given(scenes(), st.one_of(st.none(), link_poses(max_links=4)), st.sampled_from([ign.IGNITION, ign.GZ]))
def test_ign_model_bytes_equal_the_protobuf_objects(scene: Scene, draw: LinkPoses | None, msgs: ign.MessageSet) -> None:
    if draw is not None:  # some of the scene's links in the frame, some not
        names = tuple(link.name for link in scene.links)[: len(draw)] + draw.names[len(scene.links) :]
        scene = scene.with_poses(LinkPoses(draw.timestamp_ms, names, draw.robot_nums, draw.positions, draw.quaternions_wxyz))
    assert ign.model_bytes(scene, "m", msgs) == ign.model(scene, "m", msgs).SerializeToString()
    assert ign.model_v_bytes(scene, msgs) == ign.model_v(scene, msgs).SerializeToString()


@given(poses)
def test_ign_pose_bytes_with_zeros_and_negative_zeros(pose: Pose) -> None:
    signed = Pose(tuple(-0.0 if value == 0 else value for value in pose.position), pose.quaternion_wxyz)  # type: ignore[arg-type]
    for each in (pose, signed, Pose(), Pose((0.0, -0.0, 1.0), (0.0, 1.0, -0.0, 0.0))):
        scene = Scene((Link("a", 1, (Geometry(Box((1.0, 2.0, 3.0)), each, (0.0, -0.0, 0.5, 1.0)),)),))
        assert ign.model_bytes(scene) == ign.model(scene).SerializeToString()


def test_an_empty_scene_is_an_empty_marker_array() -> None:
    assert ros.marker_array_cdr(Scene(), delete_all=False) == ros.to_cdr(ros.marker_array(Scene(), delete_all=False))
    # With DELETEALL: its frame_id is "" here and "world" in the object path, as before.
    (delete_all,) = ros.from_cdr(ros.marker_array_cdr(Scene()), ros.MARKER_ARRAY).markers
    assert delete_all.action == 3


def test_zero_and_negative_zero_in_one_scene_are_not_confused_by_the_caches() -> None:
    """0.0 == -0.0 as floats, but the wire tells them apart: every cache must too."""
    geometries = tuple(
        Geometry(Box((1.0, 2.0, 3.0)), Pose((zero, 1.0, 2.0), (1.0, zero, 0.0, 0.0)), (zero, 0.5, 0.5, 1.0))
        for zero in (0.0, -0.0, 0.0, -0.0)
    )
    scene = Scene((Link("a", 1, geometries), Link("b", 2, geometries[::-1])))
    assert ign.model_bytes(scene) == ign.model(scene).SerializeToString()
    assert ros.marker_array_cdr(scene) == ros.to_cdr(ros.marker_array(scene))
