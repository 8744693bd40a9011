"""ROS 2 translators, checked against real Drake traffic, rclpy and rosbags."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import PoseArray, PoseStamped
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message
from visualization_msgs.msg import Marker, MarkerArray

from bridge.demo import TETRAHEDRON_OBJ
from bridge.errors import DecodeError, EncodeError, SceneError
from bridge.formats import ros
from bridge.scene import Geometry, Link, LinkPoses, MeshFile, Pose, Scene, frame_name
from tests.conftest import Capture
from tests.formats import oracle
from tests.formats.oracle import close
from tests.strategies import link_poses

ROLES = ["ILLUSTRATION", "PROXIMITY"]
TETRAHEDRON = np.array(
    [[float(v) for v in line.split()[1:]] for line in TETRAHEDRON_OBJ.splitlines() if line[:2] == "v "]
)


# --- load -> SolidPrimitive / Mesh / Plane ---------------------------------------------------------


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_becomes_a_shape_message(drake_capture: dict[str, Capture], role: str) -> None:
    capture = drake_capture[role]
    shapes = ros.shapes(capture.scene)
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
    assert message.__msgtype__ == ros.MESH
    return np.array([[p.x, p.y, p.z] for p in message.vertices])


def test_half_space_is_a_plane_and_reads_back() -> None:
    from bridge.scene import HalfSpace

    (posed,) = ros.shapes(Scene((Link("world", 0, (Geometry(HalfSpace(), Pose((0, 0, 1.0))),)),)))
    assert posed.typename == ros.PLANE and posed.shape.coef.tolist() == [0, 0, 1, 0]
    assert ros.shape_from_message(posed.shape) == HalfSpace()
    posed.shape.coef[3] = 2.0  # another plane is not silently the same half-space
    with pytest.raises(SceneError, match=r"coef\[3\]"):
        ros.shape_from_message(posed.shape)


@pytest.mark.parametrize("role", ROLES)
def test_shape_messages_cdr_decodes_to_the_objects(drake_capture: dict[str, Capture], role: str) -> None:
    for posed in ros.shapes(drake_capture[role].scene):
        package, _, name = posed.typename.split("/")
        cls = getattr(__import__(f"{package}.msg", fromlist=[name]), name)
        data = ros.to_cdr(posed.shape)
        assert deserialize_message(data, cls) == ros.to_rclpy(posed.shape)
        assert ros.to_rclpy(ros.from_cdr(data, posed.typename)) == ros.to_rclpy(posed.shape)
        if posed.typename == ros.SOLID_PRIMITIVE:
            assert ros.shape_from_message(posed.shape) == ros.shape_from_message(
                ros.from_rclpy(ros.to_rclpy(posed.shape))
            )


def test_a_missing_mesh_file_is_skipped_alone_with_a_warning() -> None:
    from bridge.scene import Box
    from bridge.skipped import collecting

    scene = Scene((Link("l", 0, (Geometry(MeshFile("/nowhere/mesh.obj")), Geometry(Box((1.0, 2.0, 3.0))))),))
    with collecting() as skipped:
        assert [posed.typename for posed in ros.shapes(scene)] == [ros.SOLID_PRIMITIVE]
        assert ros.shapes_cdr(scene) == [(posed.typename, ros.to_cdr(posed.shape)) for posed in ros.shapes(scene)]
        markers = ros.marker_array(scene, {"embed_mesh_files": True}).markers
    assert [marker.type for marker in markers[1:]] == [Marker.CUBE]
    assert [str(item) for item in skipped] == [
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj does not exist",
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj does not exist",
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj does not exist",
        "l geometry 0 skipped: mesh file /nowhere/mesh.obj cannot be embedded: No such file or directory",
    ]
    assert (
        ros.marker_array(scene).markers[1].mesh_resource == "file:///nowhere/mesh.obj"
    )  # by reference: fine


# --- load + draw -> MarkerArray ---------------------------------------------------------------------


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_becomes_markers_at_drakes_world_pose(
    drake_capture: dict[str, Capture], role: str
) -> None:
    capture = drake_capture[role]
    array = ros.marker_array(capture.scene)
    assert array.markers[0].action == Marker.DELETEALL
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
                assert close(cap.type == Marker.SPHERE and scale_of(cap), [2 * data[0]] * 3)
                assert close(position_of(cap), position + sign * data[1] / 2 * axis)
        elif kind == "array":
            vertices, triangles = oracle.mesh_array(geometry)
            assert first.type == Marker.TRIANGLE_LIST
            assert close([[p.x, p.y, p.z] for p in first.points], vertices[triangles.reshape(-1)])
        elif kind == "file":
            assert (
                first.type == Marker.MESH_RESOURCE and first.mesh_resource == f"file://{geometry.string_data}"
            )
            assert close(scale_of(first), data)
        elif kind == "memory":
            assert first.type == Marker.MESH_RESOURCE and first.mesh_resource == "embedded://tetrahedron.obj"
            assert first.mesh_file.filename == "tetrahedron.obj"
            assert bytes(first.mesh_file.data) == TETRAHEDRON_OBJ.encode()
    assert next(markers, None) is None
    ids = [(m.ns, m.id) for m in array.markers[1:]]
    assert len(ids) == len(set(ids))


def expected_primitive_marker(geometry_type: int, data: list[float]) -> tuple[int, list[float]] | None:
    """Marker type and scale (full size: diameters) for Drake's primitive shapes."""
    if geometry_type == oracle.BOX:
        return Marker.CUBE, data[:3]
    if geometry_type == oracle.SPHERE:
        return Marker.SPHERE, [2 * data[0]] * 3
    if geometry_type in (oracle.CYLINDER, oracle.CAPSULE):  # a capsule's first part is its cylinder
        return Marker.CYLINDER, [2 * data[0], 2 * data[0], data[1]]
    if geometry_type == oracle.ELLIPSOID:
        return Marker.SPHERE, [2 * value for value in data]
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
    objects = ros.to_rclpy(ros.marker_array(capture.scene))
    fast = ros.marker_array_cdr(capture.scene)
    assert deserialize_message(fast, MarkerArray) == objects
    assert ros.to_rclpy(ros.from_cdr(fast, ros.MARKER_ARRAY)) == objects  # rosbags reads it too
    stream = ros.MarkerStream(capture.scene)
    assert deserialize_message(stream.load_cdr, MarkerArray) == objects
    # A draw re-poses the template: equal to building the markers anew at those poses.
    moved = LinkPoses(
        capture.poses.timestamp_ms,
        capture.poses.names,
        capture.poses.robot_nums,
        capture.poses.positions + 1.0,
        np.roll(capture.poses.quaternions_wxyz, 1, axis=0),  # every link turned to another's attitude
    )
    expected = ros.to_rclpy(ros.marker_array(capture.scene.with_poses(moved), delete_all=False))
    assert deserialize_message(stream.update(moved), MarkerArray) == expected


def test_a_marker_stream_of_an_empty_scene_publishes_an_empty_array() -> None:
    stream = ros.MarkerStream(Scene(()))  # once a ValueError: no room for even one pose's view
    empty = LinkPoses(5, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))
    assert deserialize_message(stream.update(empty), MarkerArray).markers == []


def test_embedding_mesh_files_carries_their_bytes(
    drake_capture: dict[str, Capture], drake_mesh_dir: Path
) -> None:
    array = ros.marker_array(drake_capture["ILLUSTRATION"].scene, {"embed_mesh_files": True})
    embedded = [m for m in array.markers if m.mesh_resource == "embedded://tetrahedron.obj"]
    assert len(embedded) == 4  # the Mesh by file and the in-memory mesh, in two model instances
    assert all(bytes(m.mesh_file.data) == (drake_mesh_dir / "tetrahedron.obj").read_bytes() for m in embedded)
    assert not any(m.mesh_resource.startswith("file://") for m in array.markers)


def test_marker_ids_are_stable_across_loads(drake_capture: dict[str, Capture]) -> None:
    scene = drake_capture["ILLUSTRATION"].scene
    first = [(m.ns, m.id, m.type) for m in ros.marker_array(scene).markers]
    assert first == [(m.ns, m.id, m.type) for m in ros.marker_array(Scene(scene.links)).markers]


# --- draw -> PoseArray / PoseStamped, and back ------------------------------------------------------


@pytest.mark.parametrize("role", ROLES)
def test_pose_array_fast_path_matches_the_objects(drake_capture: dict[str, Capture], role: str) -> None:
    poses = raw = drake_capture[role].poses  # from Drake's draw: w-first float32 values
    data = ros.PoseArrayEncoder("world").encode(poses)
    objects = ros.to_rclpy(ros.pose_array(poses))
    decoded = deserialize_message(data, PoseArray)
    assert decoded == objects
    assert ros.to_rclpy(ros.from_cdr(data, ros.POSE_ARRAY)) == objects
    assert decoded.header.stamp.sec * 1000 + decoded.header.stamp.nanosec // 1_000_000 == poses.timestamp_ms
    for index, pose in enumerate(decoded.poses):
        w, x, y, z = raw.quaternions_wxyz[index]
        assert [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w] == [
            x,
            y,
            z,
            w,
        ]
        assert [pose.position.x, pose.position.y, pose.position.z] == raw.positions[index].tolist()
    for index, data in enumerate(ros.PoseStampedEncoder("world").encode(poses)):  # the fast path
        objects = ros.to_rclpy(ros.pose_stamped(poses, index))
        assert deserialize_message(data, PoseStamped) == objects
        assert ros.to_rclpy(ros.from_cdr(data, ros.POSE_STAMPED)) == objects
        assert objects.pose.position.x == poses.positions[index][0]


@settings(max_examples=30, deadline=None)
@given(st.lists(link_poses(max_links=5), min_size=2, max_size=5))
def test_one_pose_array_encoder_follows_changing_draws(frames: list[LinkPoses]) -> None:
    """The encoder keeps its message between draws: nothing of one draw may show in the next."""
    encoder = ros.PoseArrayEncoder("world")
    for poses in frames:
        assert deserialize_message(encoder.encode(poses), PoseArray) == ros.to_rclpy(ros.pose_array(poses))


@settings(max_examples=60, deadline=None)
@given(link_poses(), st.text(st.characters(exclude_characters="\0", exclude_categories=("Cs",)), max_size=9))
def test_draw_to_pose_array_to_draw_round_trips(poses: LinkPoses, frame_id: str) -> None:
    data = ros.PoseArrayEncoder(frame_id).encode(poses)
    assert deserialize_message(data, PoseArray) == ros.to_rclpy(ros.pose_array(poses, frame_id))
    for index, stamped in enumerate(ros.PoseStampedEncoder(frame_id).encode(poses)):
        assert deserialize_message(stamped, PoseStamped) == ros.to_rclpy(
            ros.pose_stamped(poses, index, frame_id)
        )
    names, numbers = poses.names, poses.robot_nums.tolist()
    for back in (
        ros.poses_from_pose_array_cdr(data, names, numbers),
        ros.poses_from_pose_array(ros.pose_array(poses), names, numbers),
        ros.poses_from_pose_array(ros.from_rclpy(deserialize_message(data, PoseArray)), names, numbers),
    ):
        assert back.names == poses.names and back.robot_nums.tolist() == numbers
        assert back.timestamp_ms == poses.timestamp_ms
        np.testing.assert_array_equal(back.positions, poses.positions)
        np.testing.assert_allclose(back.quaternions_wxyz, poses.quaternions_wxyz, atol=1e-15)


def pose_array_with(orientation: list[float], count: int = 2) -> Any:
    message = ros.pose_array(
        LinkPoses(0, tuple(f"l{i}" for i in range(count)), np.zeros(count, np.int32), np.zeros((count, 3)),
                  np.tile([1.0, 0, 0, 0], (count, 1)))
    )  # fmt: skip
    q = message.poses[1].orientation
    q.x, q.y, q.z, q.w = orientation
    return message


@pytest.mark.parametrize(
    ("orientation", "reason"),
    [
        ([float("nan"), 0.0, 0.0, 1.0], r"poses\[1\]: quaternion of length nan"),
        ([0.0, 0.0, 0.0, 0.0], r"poses\[1\]: quaternion of length 0 is not a rotation"),
        ([0.0, 0.0, 0.0, 2.0], r"poses\[1\]: quaternion of length 2"),
    ],
)
def test_bad_quaternions_are_refused(orientation: list[float], reason: str) -> None:
    message = pose_array_with(orientation)
    with pytest.raises(SceneError, match=reason):
        ros.poses_from_pose_array(message, ["a", "b"])
    with pytest.raises(SceneError, match=reason):
        ros.poses_from_pose_array_cdr(ros.to_cdr(message), ["a", "b"])


def test_a_nearly_unit_quaternion_is_normalised() -> None:
    back = ros.poses_from_pose_array(pose_array_with([0.0, 0.0, 0.0, 1.004]), ["a", "b"])
    assert back.quaternions_wxyz[1].tolist() == [1.0, 0.0, 0.0, 0.0]


def test_a_frame_id_with_a_nul_is_refused() -> None:
    with pytest.raises(EncodeError, match=r"header.frame_id: .* contains a NUL"):
        ros.PoseArrayEncoder("a\0b")
    with pytest.raises(EncodeError, match="not valid Unicode"):
        ros.PoseStampedEncoder("\ud800")


def test_pose_array_errors_name_what_is_wrong() -> None:
    data = ros.to_cdr(pose_array_with([0.0, 0.0, 0.0, 1.0]))
    with pytest.raises(SceneError, match="2 poses but 1 link names"):
        ros.poses_from_pose_array_cdr(data, ["a"])
    with pytest.raises(DecodeError, match="count 2 needs 112 bytes, 111 follow") as caught:
        ros.pose_array_arrays(data[:-1])
    assert caught.value.field == "poses"
    with pytest.raises(DecodeError, match="not little-endian CDR"):
        ros.pose_array_arrays(b"\x00\x00" + data[2:])
    huge = bytearray(data)
    huge[24:28] = (2**31).to_bytes(4, "little")  # the count claims 2^31 poses
    with pytest.raises(DecodeError, match="count 2147483648"):
        ros.pose_array_arrays(bytes(huge))
    with pytest.raises(DecodeError, match="not a valid CDR message"):
        ros.from_cdr(b"\x00\x01\x00\x00\xff", ros.POSE_ARRAY)


def test_pose_stamped_reads_back_as_a_pose() -> None:
    poses = LinkPoses(
        2500, ("a",), np.zeros(1, np.int32), np.array([[1.0, 2.0, 3.0]]), np.array([[0.0, 0.0, 1.0, 0.0]])
    )
    stamped = ros.from_cdr(ros.to_cdr(ros.pose_stamped(poses, 0, "map")), ros.POSE_STAMPED)
    assert stamped.header.frame_id == "map" and (stamped.header.stamp.sec, stamped.header.stamp.nanosec) == (
        2,
        5 * 10**8,
    )
    assert ros.pose_from_message(stamped.pose) == Pose((1.0, 2.0, 3.0), (0.0, 0.0, 1.0, 0.0))
    stamped.pose.position.y = float("nan")
    with pytest.raises(SceneError, match="pose.position is not finite"):
        ros.pose_from_message(stamped.pose)


def test_points_triads_and_lines_as_markers_both_paths_agree() -> None:
    from bridge.scene import Line, PointCloud, Triad

    cloud = PointCloud(np.array([[0.0, 0, 0], [1, 2, 3]]), np.array([[1.0, 0, 0], [0, 1, 0]]))
    line = Line(np.array([[0.0, 0, 0], [1, 0, 0]]), radius=0.0, closed=True)
    scene = Scene((Link("tree::a", 0, (Geometry(cloud), Geometry(Triad(2.0)), Geometry(line))),))
    objects = ros.to_rclpy(ros.marker_array(scene))
    assert deserialize_message(ros.marker_array_cdr(scene), MarkerArray) == objects
    points, triad, strip = objects.markers[1:]
    assert (points.type, points.scale.x, [c.g for c in points.colors]) == (Marker.POINTS, 0.01, [0.0, 1.0])
    assert triad.type == Marker.LINE_LIST and [p.x for p in triad.points] == [0, 2, 0, 0, 0, 0]
    assert strip.type == Marker.LINE_STRIP and len(strip.points) == 3 and strip.scale.x == 0.002
    from bridge.skipped import collecting

    with collecting() as skipped:
        ros.shapes(scene)
    assert [item.index for item in skipped if "shape_msgs has no point clouds" in item.reason] == [0]


def test_review_fixes_times_and_mesh_indices() -> None:
    from bridge.scene import TriangleMesh

    late = LinkPoses(
        2**31 * 1000, ("a",), np.zeros(1, np.int32), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]])
    )
    with pytest.raises(EncodeError, match="does not fit int32 seconds"):
        ros.PoseArrayEncoder().encode(late)
    mesh = ros.make(ros.MESH, vertices=[ros.make("geometry_msgs/msg/Point")],
                    triangles=[ros.make("shape_msgs/msg/MeshTriangle", vertex_indices=[0, 0, 5])])  # fmt: skip
    with pytest.raises(SceneError, match="refers to vertex 5 of 1"):
        ros.shape_from_message(mesh)
    assert isinstance(ros.shape_from_message(ros.make(ros.MESH)), TriangleMesh)
