"""viewer_bridge.convert, each function against the oracle its fast path is tested against (the
messages built field by field in tests/formats/*/oracle.py) or the peer that reads it (rclpy,
protobuf classes), on the demo scene: every Drake shape, two model instances, and a draw."""

from __future__ import annotations

import ast
import inspect
import subprocess
import sys
import typing
from collections.abc import Callable
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from geometry_msgs.msg import PoseArray
from rclpy.serialization import deserialize_message

from tests.formats.drake.oracle import contact_results_to_lcm, draw_from_poses
from tests.formats.foxglove.oracle import frame_transforms
from tests.formats.ign import oracle as ign_oracle
from tests.formats.ros import oracle as ros_oracle
from tests.formats.tree_viewer import oracle as tree_oracle
from viewer_bridge import convert, streams
from viewer_bridge.errors import DecodeError, InvalidSetting, SceneError, UnknownName
from viewer_bridge.examples.demo import DEMO_MESH, demo_poses, demo_scene
from viewer_bridge.examples.scenes import demo_contact_results
from viewer_bridge.formats.drake.draw import DrawDecoder
from viewer_bridge.formats.drake.image import images_to_lcm
from viewer_bridge.formats.drake.load import decode_load, load_from_scene
from viewer_bridge.formats.drake.point_cloud import cloud_to_lcm
from viewer_bridge.formats.gltf import read_gltf, write_gltf
from viewer_bridge.formats.ign.model import model_v
from viewer_bridge.formats.ros.image import image_from_cdr
from viewer_bridge.formats.ros.message_types import MESH, POSE_ARRAY, SOLID_PRIMITIVE
from viewer_bridge.formats.ros.messages import to_cdr
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr
from viewer_bridge.formats.ros.shapes import shapes_cdr
from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.formats.tree_viewer.tree import scene_from_requests
from viewer_bridge.lcmcodec.codecs import CONTACT_RESULTS, DRAW
from viewer_bridge.model.contact import ContactDrawOptions
from viewer_bridge.model.image import Image, Layout
from viewer_bridge.model.scene import PointCloud, Scene, StampedPointCloud

LOAD = load_from_scene(demo_scene()).encode()
SCENE = decode_load(LOAD)  # as the load carries it: float32 colours and dimensions
DRAW_BYTES = DRAW.encode(draw_from_poses(demo_poses(SCENE, 1.25)))
POSES = DrawDecoder().decode(DRAW_BYTES)  # the float32 values the draw carries
POSED = Scene(SCENE.links, POSES)


def test_draw_to_pose_array_is_the_message_rclpy_reads() -> None:
    data = convert.draw_to_pose_array(DRAW_BYTES)
    assert data == to_cdr(ros_oracle.pose_array(POSES, "world"))
    assert deserialize_message(data, PoseArray).header.frame_id == "world"
    assert convert.draw_to_pose_array(DRAW_BYTES, frame_id="map") == to_cdr(
        ros_oracle.pose_array(POSES, "map")
    )


def test_draw_to_tf_frames_and_stamps_every_link() -> None:
    data = convert.draw_to_tf(DRAW_BYTES, frame_prefix="proximity/")
    assert data == to_cdr(
        ros_oracle.transforms_message(POSES, (1, 250_000_000), FrameNames("world", "proximity/"))
    )
    stamped = convert.draw_to_tf(DRAW_BYTES, world_frame="map", stamp=(7, 8))
    assert stamped == to_cdr(ros_oracle.transforms_message(POSES, (7, 8), FrameNames("map")))


@pytest.mark.parametrize("message", ["Pose_V", "PosesStamped"])
def test_draw_to_pose_v_is_what_protobuf_writes(message: Any) -> None:
    oracle = ign_oracle.pose_v if message == "Pose_V" else ign_oracle.poses_stamped
    assert convert.draw_to_pose_v(DRAW_BYTES, message=message) == oracle(POSES).SerializeToString()


def test_draw_to_tree_viewer_is_the_request_director_is_sent() -> None:
    request = convert.draw_to_tree_viewer(DRAW_BYTES)
    assert tree_oracle.reference(POSES, ("drake",)) == tree_oracle.reference(
        POSES, ("drake",), request["timestamp"]
    )
    commands = request["settransform"]
    assert [command["path"] for command in commands] == [["drake", "1", name] for name in POSES.names]
    assert [command["transform"]["translation"] for command in commands] == [
        tree_oracle.to_decimals(row) for row in POSES.positions
    ]
    assert convert.draw_to_tree_viewer(DRAW_BYTES, prefix=["sim"])["settransform"][0]["path"][0] == "sim"


def test_draw_to_frame_transforms_names_the_frames_as_tf_does() -> None:
    written = FrameTransforms.FromString(convert.draw_to_frame_transforms(DRAW_BYTES))
    assert written == frame_transforms(POSES, (1, 250_000_000), FrameNames())


def test_load_to_marker_array_places_the_markers_by_the_draw() -> None:
    assert convert.load_to_marker_array(LOAD) == to_cdr(ros_oracle.marker_array(SCENE))
    posed = convert.load_to_marker_array(LOAD, draw=DRAW_BYTES, frame_id="map", embed_mesh_files=True)
    assert posed == to_cdr(ros_oracle.marker_array(POSED, {"frame_id": "map", "embed_mesh_files": True}))
    assert posed != convert.load_to_marker_array(LOAD, frame_id="map", embed_mesh_files=True)


def test_load_to_shapes_and_model_v_and_glb() -> None:
    shapes = convert.load_to_shapes(LOAD)
    assert shapes == shapes_cdr(SCENE)
    assert {shape.type for shape in shapes} == {SOLID_PRIMITIVE, MESH}  # the demo has no plane
    assert all(
        isinstance(shape, convert.TypedCdr) and shape.cdr[:4] == b"\x00\x01\x00\x00" for shape in shapes
    )
    assert convert.load_to_model_v(LOAD, draw=DRAW_BYTES) == model_v(POSED).SerializeToString()
    glb = convert.load_to_glb(LOAD, draw=DRAW_BYTES)
    assert glb[:4] == b"glTF" and int.from_bytes(glb[8:12], "little") == len(glb)  # magic, total length
    assert glb == write_gltf(POSED, binary=True)
    read_back = read_gltf(write_gltf(POSED)).to_scene()  # the same document as JSON, read back
    assert len(read_back.links) == SCENE.geometry_count()  # a node per geometry, each a triangle mesh


def test_load_to_scene_update_is_a_foxglove_message() -> None:
    update = SceneUpdate.FromString(convert.load_to_scene_update(LOAD, frame_prefix="p/"))
    assert [entity.frame_id for entity in update.entities] == [
        "world" if link.name == "world" else "p/" + link.name.replace("::", "/") for link in SCENE.links
    ]


def test_load_to_tree_viewer_reads_back_as_the_scene() -> None:
    requests = convert.load_to_tree_viewer(LOAD, draw=DRAW_BYTES)
    assert requests[0] == {**requests[0], "delete": [{"path": ["drake"]}]}
    scene = scene_from_requests(requests, [str(DEMO_MESH.parent)])  # the demo's mesh file
    assert sorted(link.name for link in scene.links) == sorted(link.name for link in SCENE.links)


def test_contacts_to_marker_array_takes_the_drawing_options() -> None:
    results = demo_contact_results()
    data = CONTACT_RESULTS.encode(contact_results_to_lcm(results))
    drawing = ContactDrawOptions(force_scale=0.05, surfaces=False)
    expected = to_cdr(ros_oracle.contact_marker_array(results, drawing, {"frame_id": "map"}))
    assert (
        convert.contacts_to_marker_array(data, force_scale=0.05, surfaces=False, frame_id="map") == expected
    )


def test_point_clouds_both_ways() -> None:
    points = np.array([[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]])
    colors = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    data = cloud_to_lcm(StampedPointCloud(PointCloud(points, colors), "", 1_500_000))
    cloud2 = convert.point_cloud_to_point_cloud2(data, frame_id="camera")
    stamped = cloud_from_cdr(cloud2)
    assert (stamped.frame, stamped.time_us) == ("camera", 1_500_000)
    assert np.array_equal(stamped.cloud.points, points)
    assert convert.point_cloud2_to_point_cloud(cloud2) == cloud_to_lcm(stamped)


def test_images_to_numpy_and_ros() -> None:
    rgba = np.arange(4 * 3 * 4, dtype=np.uint8).reshape(4, 3, 4)
    depth = np.full((4, 3, 1), 1500, dtype=np.uint16)
    images = [Image("rgb", 2_000_000, Layout.RGBA, rgba), Image("depth", 2_000_000, Layout.DEPTH, depth)]
    data = images_to_lcm(images, 2_000_000, compress=True)
    decoded = convert.image_array_to_images(data)
    assert [image.name for image in decoded] == ["rgb", "depth"]
    assert np.array_equal(decoded[0].pixels, rgba) and np.array_equal(decoded[1].pixels, depth)
    ros_images = convert.image_array_to_ros_images(data, frame_id="cam", drop_alpha=True, depth="32FC1")
    rgb = image_from_cdr(ros_images["rgb"])
    assert (rgb.frame_id, rgb.time_us, rgb.image.layout) == ("cam", 2_000_000, Layout.RGB)
    assert np.array_equal(rgb.image.pixels, rgba[:, :, :3])
    assert np.array_equal(
        image_from_cdr(ros_images["depth"]).image.pixels, np.full((4, 3, 1), 1.5, np.float32)
    )


def test_pose_array_to_draw_takes_the_names_from_the_load() -> None:
    pose_array = convert.draw_to_pose_array(DRAW_BYTES)
    assert convert.pose_array_to_draw(pose_array, load=LOAD) == DRAW_BYTES
    assert (
        convert.pose_array_to_draw(pose_array, link_names=POSES.names, robot_nums=[1] * len(POSES))
        == DRAW_BYTES
    )
    unnamed = DrawDecoder().decode(convert.pose_array_to_draw(pose_array))
    assert unnamed.names == tuple(f"pose_{index}" for index in range(len(POSES)))
    with pytest.raises(SceneError, match="8 poses, 2 link names"):
        convert.pose_array_to_draw(pose_array, link_names=["a", "b"])


def test_cdr_to_rclpy_is_rclpys_own_message() -> None:
    pose_array = convert.draw_to_pose_array(DRAW_BYTES)
    assert convert.cdr_to_rclpy(pose_array, POSE_ARRAY) == deserialize_message(pose_array, PoseArray)
    # A type its package does not have, and bytes that are no CDR of the type: typed errors.
    with pytest.raises(
        UnknownName, match="'geometry_msgs/msg/PoseArrays' .did you mean 'geometry_msgs/msg/PoseArray'"
    ):
        convert.cdr_to_rclpy(pose_array, "geometry_msgs/msg/PoseArrays")
    with pytest.raises(
        DecodeError, match=r"^geometry_msgs/msg/PoseArray.<message> at byte 0: failed to deserialize"
    ):
        convert.cdr_to_rclpy(pose_array[:9], POSE_ARRAY)


def test_an_option_out_of_range_is_invalid_setting() -> None:
    data = CONTACT_RESULTS.encode(contact_results_to_lcm(demo_contact_results()))
    with pytest.raises(InvalidSetting, match="force_scale"):
        convert.contacts_to_marker_array(data, force_scale=-1.0)


def test_bad_bytes_are_a_decode_error() -> None:
    with pytest.raises(DecodeError):
        convert.draw_to_pose_array(DRAW_BYTES[:-3])
    with pytest.raises(DecodeError):
        convert.load_to_marker_array(DRAW_BYTES)


def test_a_misspelt_option_is_a_type_error() -> None:
    with pytest.raises(TypeError, match="frame_idd"):
        convert.load_to_marker_array(LOAD, frame_idd="map")  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="mesage"):
        convert.draw_to_pose_v(DRAW_BYTES, mesage="Pose_V")  # type: ignore[call-arg]


def public_functions(module: ModuleType) -> list[tuple[str, Callable[..., object]]]:
    """The module's public functions, and the public methods (with `__init__`) of its public classes."""
    found: list[tuple[str, Callable[..., object]]] = []
    for name in module.__all__:
        value = getattr(module, name)
        if inspect.isfunction(value):
            found.append((name, value))
        elif inspect.isclass(value) and not issubclass(value, tuple):  # a NamedTuple's are generated
            found += [(f"{name}.{method}", function) for method, function in inspect.getmembers(value, inspect.isfunction)
                      if not method.startswith("_") or method == "__init__"]  # fmt: skip
    return found


def annotation_namespace(function: Callable[..., object]) -> dict[str, Any]:
    """The globals of the function's module with the names it imports for the type checker only
    (`if TYPE_CHECKING:`), so that every annotation it writes can be evaluated."""
    module = sys.modules[function.__module__]
    namespace = dict(vars(module))
    for node in ast.parse(inspect.getsource(module)).body:
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            exec(
                compile(ast.Module(body=node.body, type_ignores=[]), str(module.__file__), "exec"), namespace
            )
    return namespace


def hints(function: Callable[..., object]) -> dict[str, Any]:
    """The function's parameter and return types, evaluated."""
    return typing.get_type_hints(function, annotation_namespace(function))


def mentions_any(hint: object) -> bool:
    """Whether a type, or any type it is built of (`dict[str, Any]`, `list[X | Any]`), is `Any`."""
    return hint is Any or any(mentions_any(argument) for argument in typing.get_args(hint))


@pytest.mark.parametrize("module", [convert, streams])
def test_no_public_signature_mentions_any(module: ModuleType) -> None:
    functions = public_functions(module)
    assert len(functions) > 10
    with_any = [name for name, function in functions if any(map(mentions_any, hints(function).values()))]
    assert with_any == []


def test_mentions_any_finds_any_however_deep() -> None:
    assert mentions_any(dict[str, list[int | Any]]) and not mentions_any(dict[str, list[int | None]])


def test_every_option_is_keyword_only() -> None:
    """Past the message's bytes (and `cdr_to_rclpy`'s type name, which is no option), every
    parameter is named: a call cannot pass an option in the wrong place by position."""
    functions = public_functions(convert)
    for name, function in functions:
        parameters = list(inspect.signature(function).parameters.values())
        positional = [p.name for p in parameters if p.kind is not inspect.Parameter.KEYWORD_ONLY]
        assert positional in (["data"], ["data", "typename"]), name
    # all of them were looked at
    assert sum(name.startswith(("draw_", "load_")) for name, _ in functions) == 13


def test_importing_the_facade_imports_no_optional_dependency() -> None:
    heavy = ["rclpy", "moderngl", "foxglove", "foxglove_schemas_protobuf", "zenoh", "zmq", "trimesh", "scipy"]
    code = f"import sys, viewer_bridge.convert, viewer_bridge.streams; print([m for m in {heavy} if m in sys.modules])"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
