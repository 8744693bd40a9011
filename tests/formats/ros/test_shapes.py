"""ROS 2 shape_msgs (SolidPrimitive, Mesh, Plane) from Drake's loads, checked against real Drake
traffic, rclpy and rosbags, and read back."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.conftest import Capture
from tests.formats import oracle
from tests.formats.oracle import close
from tests.formats.ros import oracle as ros_oracle
from tests.optional import peer
from viewer_bridge.errors import EncodeError, SceneError
from viewer_bridge.examples.demo import TETRAHEDRON_OBJ
from viewer_bridge.formats.ros.message_types import MESH, PLANE, SOLID_PRIMITIVE
from viewer_bridge.formats.ros.messages import from_cdr, from_rclpy, make, to_cdr, to_rclpy
from viewer_bridge.formats.ros.poses import PoseArrayEncoder
from viewer_bridge.formats.ros.shapes import shape_from_message, shapes_cdr
from viewer_bridge.model.scene import Geometry, Link, LinkPoses, MeshFile, Pose, Scene, frame_name

serialization = peer("rclpy.serialization")
markers_msgs = peer("visualization_msgs.msg")

ROLES = ["ILLUSTRATION", "PROXIMITY"]
TETRAHEDRON = np.array(
    [[float(v) for v in line.split()[1:]] for line in TETRAHEDRON_OBJ.splitlines() if line[:2] == "v "]
)


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_becomes_a_shape_message(drake_capture: dict[str, Capture], role: str) -> None:
    capture = drake_capture[role]
    shapes = ros_oracle.shapes(capture.scene)
    raw = capture.raw_geometries()
    assert len(shapes) == len(raw)  # nothing dropped, nothing split
    seen = set()
    for posed, (link_name, geometry) in zip(shapes, raw, strict=True):
        assert posed.frame_id == frame_name(link_name)
        position, orientation = posed.pose.position, posed.pose.orientation
        assert close([position.x, position.y, position.z], geometry.position)
        assert close([orientation.x, orientation.y, orientation.z, orientation.w], oracle.xyzw(geometry))
        data, message = geometry.float_data, posed.shape
        kind = oracle.mesh_kind(geometry) or geometry.type
        seen.add(kind)
        if geometry.type == oracle.BOX:
            assert message.type == 1 and close(message.dimensions, data[:3])
        elif geometry.type == oracle.SPHERE:
            assert message.type == 2 and close(message.dimensions, data[:1])
        elif geometry.type == oracle.CYLINDER:  # SolidPrimitive is HEIGHT first, Drake radius first
            assert message.type == 3 and close(message.dimensions, [data[1], data[0]])
        elif geometry.type == oracle.CAPSULE:
            vertices = mesh_vertices(message)
            assert np.abs(vertices[:, 2]).max() == pytest.approx(data[1] / 2 + data[0], rel=1e-6)
            assert np.abs(vertices[:, :2]).max() == pytest.approx(data[0], rel=1e-6)
        elif geometry.type == oracle.ELLIPSOID:
            extent = np.abs(mesh_vertices(message)).max(axis=0)
            assert (extent <= np.asarray(data) * (1 + 1e-6)).all() and (
                extent >= 0.85 * np.asarray(data)
            ).all()
        elif kind == "array":
            vertices, triangles = oracle.mesh_array(geometry)
            assert close(mesh_vertices(message).tolist(), vertices)
            assert [list(t.vertex_indices) for t in message.triangles] == triangles.tolist()
        else:  # a mesh file, or an in-memory OBJ: both read with trimesh, then scaled
            scale = data if len(data) == 3 else [1.0, 1.0, 1.0]
            assert close(mesh_vertices(message).tolist(), TETRAHEDRON * scale)
    expected = {1, 2, 3, 5, 6, "array"} | ({"file", "memory"} if role == "ILLUSTRATION" else set())
    assert seen == expected


def mesh_vertices(message: Any) -> np.ndarray:
    assert message.__msgtype__ == MESH
    return np.array([[p.x, p.y, p.z] for p in message.vertices])


def test_half_space_is_a_plane_and_reads_back() -> None:
    from viewer_bridge.model.scene import HalfSpace

    (posed,) = ros_oracle.shapes(Scene((Link("world", 0, (Geometry(HalfSpace(), Pose((0, 0, 1.0))),)),)))
    assert posed.typename == PLANE and posed.shape.coef.tolist() == [0, 0, 1, 0]
    assert shape_from_message(posed.shape) == HalfSpace()
    posed.shape.coef[3] = 2.0  # another plane is not silently the same half-space
    with pytest.raises(SceneError, match=r"coef\[3\]"):
        shape_from_message(posed.shape)


@pytest.mark.parametrize("role", ROLES)
def test_shape_messages_cdr_decodes_to_the_objects(drake_capture: dict[str, Capture], role: str) -> None:
    for posed in ros_oracle.shapes(drake_capture[role].scene):
        package, _, name = posed.typename.split("/")
        cls = getattr(__import__(f"{package}.msg", fromlist=[name]), name)
        data = to_cdr(posed.shape)
        assert serialization.deserialize_message(data, cls) == to_rclpy(posed.shape)
        assert to_rclpy(from_cdr(data, posed.typename)) == to_rclpy(posed.shape)
        if posed.typename == SOLID_PRIMITIVE:
            assert shape_from_message(posed.shape) == shape_from_message(from_rclpy(to_rclpy(posed.shape)))


def test_a_missing_mesh_file_is_skipped_alone_with_a_warning() -> None:
    from viewer_bridge.model.scene import Box
    from viewer_bridge.model.skipped import collecting

    scene = Scene((Link("l", 0, (Geometry(MeshFile("/nowhere/mesh.obj")), Geometry(Box((1.0, 2.0, 3.0))))),))
    with collecting() as skipped:
        assert [posed.typename for posed in ros_oracle.shapes(scene)] == [SOLID_PRIMITIVE]
        assert shapes_cdr(scene) == [
            (posed.typename, to_cdr(posed.shape)) for posed in ros_oracle.shapes(scene)
        ]
        markers = ros_oracle.marker_array(scene, {"embed_mesh_files": True}).markers
    assert [marker.type for marker in markers[1:]] == [markers_msgs.Marker.CUBE]
    assert [str(item) for item in skipped] == [
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj does not exist",
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj does not exist",
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj does not exist",
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj cannot be embedded: No such file or directory",
    ]
    assert (
        ros_oracle.marker_array(scene).markers[1].mesh_resource == "file:///nowhere/mesh.obj"
    )  # by reference: fine


def test_review_fixes_times_and_mesh_indices() -> None:
    from viewer_bridge.model.scene import TriangleMesh

    late = LinkPoses(
        2**31 * 1000, ("a",), np.zeros(1, np.int32), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]])
    )
    with pytest.raises(EncodeError, match="does not fit int32 seconds"):
        PoseArrayEncoder().encode(late)
    mesh = make(MESH, vertices=[make("geometry_msgs/msg/Point")],
                triangles=[make("shape_msgs/msg/MeshTriangle", vertex_indices=[0, 0, 5])])  # fmt: skip
    with pytest.raises(SceneError, match="refers to vertex 5 of 1"):
        shape_from_message(mesh)
    assert isinstance(shape_from_message(make(MESH)), TriangleMesh)
