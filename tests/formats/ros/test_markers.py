"""ROS 2 MarkerArrays from Drake's loads and draws, checked against real Drake traffic, rclpy and
rosbags: the CDR fast paths against the objects."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import Capture
from tests.formats import oracle
from tests.formats.oracle import close
from tests.formats.ros import oracle as ros_oracle
from tests.optional import peer
from viewer_bridge.examples.demo import TETRAHEDRON_OBJ
from viewer_bridge.formats.ros.markers import MarkerStream, marker_array_cdr
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY
from viewer_bridge.formats.ros.messages import from_cdr, to_rclpy
from viewer_bridge.model.scene import Geometry, Link, LinkPoses, Pose, Scene, frame_name

serialization = peer("rclpy.serialization")
markers_msgs = peer("visualization_msgs.msg")

ROLES = ["ILLUSTRATION", "PROXIMITY"]


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_becomes_markers_at_drakes_world_pose(
    drake_capture: dict[str, Capture], role: str
) -> None:
    capture = drake_capture[role]
    array = ros_oracle.marker_array(capture.scene)
    assert array.markers[0].action == markers_msgs.Marker.DELETEALL
    markers = iter(array.markers[1:])
    for link_name, geometry in capture.raw_geometries():
        link_pose = capture.scene.poses.pose_of(link_name) if link_name in capture.poses.names else Pose()
        position, xyzw = oracle.world_pose(link_pose.position, link_pose.quaternion_wxyz, geometry)
        data = geometry.float_data
        kind = oracle.mesh_kind(geometry) or geometry.type
        parts = 3 if geometry.type == oracle.CAPSULE else 1
        group = [next(markers) for _ in range(parts)]
        for marker in group:
            assert marker.ns == frame_name(link_name) and marker.header.frame_id == "world"
            assert close([marker.color.r, marker.color.g, marker.color.b, marker.color.a], geometry.color)
            assert oracle.same_rotation(xyzw_of(marker), xyzw)
        first = group[0]
        primitive = expected_primitive_marker(geometry.type, data)
        if primitive is not None:
            assert first.type == primitive[0] and close(scale_of(first), primitive[1])
            assert close(position_of(first), position)
        if geometry.type == oracle.CAPSULE:  # the caps sit at +-L/2 along the capsule's axis
            axis = oracle.transform(position, [xyzw[3], *xyzw[:3]]).rotation().matrix()[:, 2]
            for cap, sign in zip(group[1:], (1, -1), strict=True):
                assert close(cap.type == markers_msgs.Marker.SPHERE and scale_of(cap), [2 * data[0]] * 3)
                assert close(position_of(cap), position + sign * data[1] / 2 * axis)
        elif kind == "array":
            vertices, triangles = oracle.mesh_array(geometry)
            assert first.type == markers_msgs.Marker.TRIANGLE_LIST
            assert close([[p.x, p.y, p.z] for p in first.points], vertices[triangles.reshape(-1)])
        elif kind == "file":
            assert (
                first.type == markers_msgs.Marker.MESH_RESOURCE
                and first.mesh_resource == f"file://{geometry.string_data}"
            )
            assert close(scale_of(first), data)
        elif kind == "memory":
            assert (
                first.type == markers_msgs.Marker.MESH_RESOURCE
                and first.mesh_resource == "embedded://tetrahedron.obj"
            )
            assert first.mesh_file.filename == "tetrahedron.obj"
            assert bytes(first.mesh_file.data) == TETRAHEDRON_OBJ.encode()
    assert next(markers, None) is None
    ids = [(m.ns, m.id) for m in array.markers[1:]]
    assert len(ids) == len(set(ids))


def expected_primitive_marker(geometry_type: int, data: list[float]) -> tuple[int, list[float]] | None:
    """Marker type and scale (full size: diameters) for Drake's primitive shapes."""
    if geometry_type == oracle.BOX:
        return markers_msgs.Marker.CUBE, data[:3]
    if geometry_type == oracle.SPHERE:
        return markers_msgs.Marker.SPHERE, [2 * data[0]] * 3
    if geometry_type in (oracle.CYLINDER, oracle.CAPSULE):  # a capsule's first part is its cylinder
        return markers_msgs.Marker.CYLINDER, [2 * data[0], 2 * data[0], data[1]]
    if geometry_type == oracle.ELLIPSOID:
        return markers_msgs.Marker.SPHERE, [2 * value for value in data]
    return None


def xyzw_of(marker: Any) -> list[float]:
    q = marker.pose.orientation
    return [q.x, q.y, q.z, q.w]


def position_of(marker: Any) -> list[float]:
    p = marker.pose.position
    return [p.x, p.y, p.z]


def scale_of(marker: Any) -> list[float]:
    return [marker.scale.x, marker.scale.y, marker.scale.z]


@pytest.mark.parametrize("role", ROLES)
def test_marker_cdr_paths_decode_to_the_objects(drake_capture: dict[str, Capture], role: str) -> None:
    capture = drake_capture[role]
    objects = to_rclpy(ros_oracle.marker_array(capture.scene))
    fast = marker_array_cdr(capture.scene)
    assert serialization.deserialize_message(fast, markers_msgs.MarkerArray) == objects
    assert to_rclpy(from_cdr(fast, MARKER_ARRAY)) == objects  # rosbags reads it too
    stream = MarkerStream(capture.scene)
    assert serialization.deserialize_message(stream.load_cdr, markers_msgs.MarkerArray) == objects
    # A draw re-poses the template: equal to building the markers anew at those poses.
    moved = LinkPoses(
        capture.poses.timestamp_ms,
        capture.poses.names,
        capture.poses.robot_nums,
        capture.poses.positions + 1.0,
        np.roll(capture.poses.quaternions_wxyz, 1, axis=0),  # every link turned to another's attitude
    )
    expected = to_rclpy(ros_oracle.marker_array(capture.scene.with_poses(moved), delete_all=False))
    assert serialization.deserialize_message(stream.update(moved), markers_msgs.MarkerArray) == expected


def test_a_marker_stream_of_an_empty_scene_publishes_an_empty_array() -> None:
    stream = MarkerStream(Scene(()))  # once a ValueError: no room for even one pose's view
    empty = LinkPoses(5, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))
    assert serialization.deserialize_message(stream.update(empty), markers_msgs.MarkerArray).markers == []


def test_embedding_mesh_files_carries_their_bytes(
    drake_capture: dict[str, Capture], drake_mesh_dir: Path
) -> None:
    array = ros_oracle.marker_array(drake_capture["ILLUSTRATION"].scene, {"embed_mesh_files": True})
    embedded = [m for m in array.markers if m.mesh_resource == "embedded://tetrahedron.obj"]
    assert len(embedded) == 4  # the Mesh by file and the in-memory mesh, in two model instances
    assert all(bytes(m.mesh_file.data) == (drake_mesh_dir / "tetrahedron.obj").read_bytes() for m in embedded)
    assert not any(m.mesh_resource.startswith("file://") for m in array.markers)


def test_marker_ids_are_stable_across_loads(drake_capture: dict[str, Capture]) -> None:
    scene = drake_capture["ILLUSTRATION"].scene
    first = [(m.ns, m.id, m.type) for m in ros_oracle.marker_array(scene).markers]
    assert first == [(m.ns, m.id, m.type) for m in ros_oracle.marker_array(Scene(scene.links)).markers]


def test_points_triads_and_lines_as_markers_both_paths_agree() -> None:
    from viewer_bridge.model.scene import Line, PointCloud, Triad

    cloud = PointCloud(np.array([[0.0, 0, 0], [1, 2, 3]]), np.array([[1.0, 0, 0], [0, 1, 0]]))
    line = Line(np.array([[0.0, 0, 0], [1, 0, 0]]), radius=0.0, closed=True)
    scene = Scene((Link("tree::a", 0, (Geometry(cloud), Geometry(Triad(2.0)), Geometry(line))),))
    objects = to_rclpy(ros_oracle.marker_array(scene))
    assert serialization.deserialize_message(marker_array_cdr(scene), markers_msgs.MarkerArray) == objects
    points, triad, strip = objects.markers[1:]
    assert (points.type, points.scale.x, [c.g for c in points.colors]) == (
        markers_msgs.Marker.POINTS,
        0.01,
        [0.0, 1.0],
    )
    assert triad.type == markers_msgs.Marker.LINE_LIST and [p.x for p in triad.points] == [0, 2, 0, 0, 0, 0]
    assert strip.type == markers_msgs.Marker.LINE_STRIP and len(strip.points) == 3 and strip.scale.x == 0.002
    from viewer_bridge.model.skipped import collecting

    with collecting() as skipped:
        ros_oracle.shapes(scene)
    assert [item.index for item in skipped if "shape_msgs has no point clouds" in item.reason] == [0]
