"""Pure converters: one Drake LCM message in, one target message out, in one call each.

Every function here takes the bytes of one message (as LCM, `lcm-logger` or a ROS 2 subscriber
gives them) and returns bytes or plain objects. None of them keeps state between calls, does
I/O (except reading a mesh file a target must carry as triangles) or imports a transport,
rclpy, Foxglove's packages or trimesh before it needs them. Options are keyword-only
parameters, so a misspelt option is a `TypeError`; an option left at `None` keeps the default
of the format's table (`mappings/`).

```python
from viewer_bridge import convert

pose_array = convert.draw_to_pose_array(draw_bytes)     # geometry_msgs/PoseArray CDR
request = convert.draw_to_tree_viewer(draw_bytes)       # {"settransform": [...], ...}
markers = convert.load_to_marker_array(load_bytes, draw=draw_bytes)
```

A draw carries its links' names and robot numbers, so a draw converts alone. A load has no
poses: the functions that place geometry in the world take the draw that poses it as `draw=`
(without one, every link sits at the origin). PoseArray carries no names: going back to a
draw, they come from `link_names=` or from the load (`load=`). Bad bytes raise
`viewer_bridge.errors.DecodeError`; a scene a target cannot express, `SceneError`; a missing
optional dependency, `MissingExtra` naming the pip command.

For a stream of many messages, the classes in `viewer_bridge.streams` keep what repeats
between frames (link names, message templates) and convert each draw faster.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.drake.image import read_image_array, unpack
from viewer_bridge.formats.drake.load import decode_load
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm, cloud_to_lcm
from viewer_bridge.formats.foxglove.transforms import FrameTransformsEncoder
from viewer_bridge.formats.gltf import write_gltf
from viewer_bridge.formats.ign.model import model_v_bytes
from viewer_bridge.formats.ign.poses import PosesEncoder
from viewer_bridge.formats.ros.cdr import time_parts, time_parts_from_us
from viewer_bridge.formats.ros.contact import contact_marker_array_cdr
from viewer_bridge.formats.ros.image import image_to_cdr
from viewer_bridge.formats.ros.markers import marker_array_cdr
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr, cloud_to_cdr
from viewer_bridge.formats.ros.poses import PoseArrayEncoder, pose_array_arrays, poses_from_pose_array_cdr
from viewer_bridge.formats.ros.shapes import shapes_cdr
from viewer_bridge.formats.ros.tf import WORLD, FrameNames, TransformsEncoder
from viewer_bridge.formats.tree_viewer.requests import DEFAULT_PREFIX, draw_request, load_requests
from viewer_bridge.lcmcodec import Buffer
from viewer_bridge.model.contact import ContactDrawOptions
from viewer_bridge.model.image import Image, Layout, depth_rep117
from viewer_bridge.model.scene import LinkPoses, Scene
from viewer_bridge.model.sim_time import sec_nsec_from_ms
from viewer_bridge.util.extras import missing, require

# --- reading Drake's messages --------------------------------------------------------------------


def draw_to_link_poses(data: Buffer) -> LinkPoses:
    """An `lcmt_viewer_draw` as arrays: names, robot numbers, positions N x 3, w-first quaternions N x 4."""
    return DrawDecoder().decode(data)


def load_to_scene(data: Buffer, *, draw: Buffer | None = None) -> Scene:
    """An `lcmt_viewer_load_robot` as the scene model, its links posed by `draw` when given."""
    scene = decode_load(data)
    return scene if draw is None else scene.with_poses(draw_to_link_poses(draw))


# --- a draw (every link's pose) ------------------------------------------------------------------


def draw_to_pose_array(data: bytes, frame_id: str = "world") -> bytes:
    """A draw as `geometry_msgs/PoseArray` CDR in the draw's link order, stamped with its sim time."""
    return PoseArrayEncoder(frame_id).encode(draw_to_link_poses(data))


def draw_to_tf(
    data: bytes, *, world_frame: str = WORLD, frame_prefix: str = "", stamp: tuple[int, int] | None = None
) -> bytes:
    """A draw as `tf2_msgs/TFMessage` CDR: `world_frame` -> every link, frames named as in the
    field (`plant::iiwa::link_0` -> `frame_prefix` + `plant/iiwa/link_0`). `stamp` is (sec,
    nanosec); None: the draw's sim time."""
    poses = draw_to_link_poses(data)
    encoder = TransformsEncoder(FrameNames(world_frame, frame_prefix))
    return encoder.encode(poses, stamp or time_parts(poses.timestamp_ms))


def draw_to_pose_v(data: bytes, *, message: Literal["Pose_V", "PosesStamped"] = "Pose_V") -> bytes:
    """A draw as ign/gz `Pose_V` bytes (or the legacy `PosesStamped`), a named Pose per link."""
    return PosesEncoder(message).encode(draw_to_link_poses(data))


def draw_to_tree_viewer(data: bytes, *, prefix: Sequence[str] = DEFAULT_PREFIX) -> dict[str, Any]:
    """A draw as the request Director's tree viewer is sent: a `settransform` per link at
    `[*prefix, robot_num, link name]`, numbers rounded to 8 decimals. `envelope.encode` of it
    (`viewer_bridge.formats.tree_viewer.envelope`) is the `viewer2_comms_t` to publish."""
    return draw_request(draw_to_link_poses(data), prefix)


def draw_to_frame_transforms(
    data: bytes, *, world_frame: str = WORLD, frame_prefix: str = "", stamp: tuple[int, int] | None = None
) -> bytes:
    """A draw as `foxglove.FrameTransforms` protobuf bytes, framed as `draw_to_tf` frames it."""
    poses = draw_to_link_poses(data)
    encoder = FrameTransformsEncoder(FrameNames(world_frame, frame_prefix))
    return encoder.encode(poses, stamp or sec_nsec_from_ms(poses.timestamp_ms))


# --- a load (every link's geometry) --------------------------------------------------------------


def load_to_marker_array(
    data: bytes,
    *,
    draw: bytes | None = None,
    frame_id: str | None = None,
    embed_mesh_files: bool | None = None,
    point_size: float | None = None,
) -> bytes:
    """A load as `visualization_msgs/MarkerArray` CDR (DELETEALL first), each marker placed by
    `draw`. `embed_mesh_files`: mesh files as triangle lists, for an RViz that cannot read
    them; `point_size`: metres, for point clouds."""
    options = _given(frame_id=frame_id, embed_mesh_files=embed_mesh_files, point_size=point_size)
    return marker_array_cdr(load_to_scene(data, draw=draw), options)


def load_to_shapes(data: bytes) -> list[tuple[str, bytes]]:
    """A load as shape_msgs CDR, one message per geometry in the link's frame: (type name, CDR),
    the type `shape_msgs/msg/SolidPrimitive`, `Mesh` or `Plane`."""
    return shapes_cdr(decode_load(data))


def load_to_model_v(data: bytes, *, draw: bytes | None = None) -> bytes:
    """A load as ign/gz `Model_V` bytes: a Model per robot_num, a Link per Drake link (posed by
    `draw`), a Visual per geometry."""
    return model_v_bytes(load_to_scene(data, draw=draw))


def load_to_scene_update(
    data: bytes, *, world_frame: str = WORLD, frame_prefix: str = "", stamp: tuple[int, int] = (0, 0)
) -> bytes:
    """A load as `foxglove.SceneUpdate` protobuf bytes: an entity per link, in its link's frame
    (named as `draw_to_tf` names them). Needs the `foxglove` extra."""
    try:
        from viewer_bridge.formats.foxglove.scene import scene_update
    except ImportError as error:
        raise missing(error, "load_to_scene_update") from None
    update = scene_update(decode_load(data), FrameNames(world_frame, frame_prefix), stamp)
    return bytes(update.SerializeToString())


def load_to_glb(data: bytes, *, draw: bytes | None = None) -> bytes:
    """A load as a binary glTF 2.0 (`.glb`) document, every shape as triangles, posed by `draw`."""
    return write_gltf(load_to_scene(data, draw=draw), binary=True)


def load_to_tree_viewer(
    data: bytes, *, draw: bytes | None = None, prefix: Sequence[str] = DEFAULT_PREFIX
) -> list[dict[str, Any]]:
    """A load as the two requests Director's tree viewer is sent: delete the tree under
    `prefix`, then a `setgeometry` per geometry (and a `settransform` per link of `draw`)."""
    return load_requests(load_to_scene(data, draw=draw), prefix)


# --- Drake's other messages ----------------------------------------------------------------------


def contacts_to_marker_array(
    data: bytes,
    *,
    force_scale: float | None = None,
    moment_scale: float | None = None,
    arrow_radius: float | None = None,
    min_length: float | None = None,
    pressure_range: tuple[float, float] | None = None,
    surfaces: bool | None = None,
    frame_id: str | None = None,
) -> bytes:
    """An `lcmt_contact_results_for_viz` as MarkerArray CDR, as meldis draws it: force and
    moment arrows, pressure-coloured hydroelastic surfaces. None: the default of
    `viewer_bridge.model.contact.ContactDrawOptions`."""
    drawing = ContactDrawOptions(
        **_given(
            force_scale=force_scale,
            moment_scale=moment_scale,
            arrow_radius=arrow_radius,
            min_length=min_length,
            pressure_range=pressure_range,
            surfaces=surfaces,
        )
    )
    return contact_marker_array_cdr(decode_contact_results(data), drawing, _given(frame_id=frame_id))


def point_cloud_to_point_cloud2(data: bytes, *, frame_id: str = WORLD) -> bytes:
    """An `lcmt_point_cloud` as `sensor_msgs/PointCloud2` CDR; `frame_id` for a cloud without a frame."""
    return cloud_to_cdr(cloud_from_lcm(data), frame_id)


def point_cloud2_to_point_cloud(data: bytes) -> bytes:
    """A `sensor_msgs/PointCloud2` (x, y, z and optional normals and rgb) as an `lcmt_point_cloud`."""
    return cloud_to_lcm(cloud_from_cdr(data))


def image_array_to_images(data: bytes) -> list[Image]:
    """An `lcmt_image_array` as images whose `pixels` are numpy arrays (height x width x
    channels), decompressed; named by Drake's port (`rgb`, `depth`, `label`)."""
    return [unpack(packed) for packed in read_image_array(data).images]


def image_array_to_ros_images(
    data: bytes, *, frame_id: str = "camera", drop_alpha: bool = False, depth: Literal["16UC1", "32FC1"] = "16UC1"
) -> dict[str, bytes]:
    """An `lcmt_image_array` as `sensor_msgs/Image` CDR per image name, stamped with its sim time.

    `drop_alpha`: rgba8 -> rgb8; `depth`: `32FC1` writes depth in metres (REP 117), as a float
    depth image always is.
    """
    out = {}
    for image in image_array_to_images(data):
        if drop_alpha:
            image = image.without_alpha()
        if image.layout is Layout.DEPTH and (depth == "32FC1" or image.pixels.dtype.kind == "f"):
            image = depth_rep117(image)
        out[image.name] = image_to_cdr(image, frame_id, time_parts_from_us(image.time_us))
    return out


# --- back to Drake, and to rclpy -----------------------------------------------------------------


def pose_array_to_draw(
    data: bytes,
    *,
    link_names: Sequence[str] | None = None,
    robot_nums: Sequence[int] | None = None,
    load: bytes | None = None,
) -> bytes:
    """A `geometry_msgs/PoseArray` as an `lcmt_viewer_draw`. PoseArray has no names: they come
    from `link_names` (with `robot_nums`, else 0), else from `load`'s links in order but for
    `world` (whose pose a draw leaves out, as Drake's does), else `pose_0`, `pose_1`, ...
    `SceneError` when their count differs from the poses'."""
    count = pose_array_arrays(data)[2].shape[0]
    if link_names is None and load is not None:
        links = [link for link in decode_load(load).links if link.name != WORLD]
        link_names = [link.name for link in links]
        robot_nums = [link.robot_num for link in links] if robot_nums is None else robot_nums
    names = [f"pose_{index}" for index in range(count)] if link_names is None else list(link_names)
    if len(names) != count:
        raise SceneError(f"the PoseArray has {count} poses, {len(names)} link names given")
    return DrawEncoder().encode(poses_from_pose_array_cdr(data, names, robot_nums))


def cdr_to_rclpy(data: bytes, typename: str) -> Any:
    """ROS 2 CDR as the rclpy message object of `typename` (`geometry_msgs/msg/PoseArray`).
    Needs the `ros` extra (rclpy and the message packages)."""
    serialization = require("rclpy.serialization", "cdr_to_rclpy")
    package, _, name = typename.rpartition("/msg/") if "/msg/" in typename else typename.partition("/")
    message_class = getattr(require(f"{package}.msg", "cdr_to_rclpy"), name)
    return serialization.deserialize_message(data, message_class)


def _given(**options: Any) -> dict[str, Any]:
    """The options set (not None): what overrides a table's or a model's defaults."""
    return {name: value for name, value in options.items() if value is not None}


__all__ = [
    "cdr_to_rclpy",
    "contacts_to_marker_array",
    "draw_to_frame_transforms",
    "draw_to_link_poses",
    "draw_to_pose_array",
    "draw_to_pose_v",
    "draw_to_tf",
    "draw_to_tree_viewer",
    "image_array_to_images",
    "image_array_to_ros_images",
    "load_to_glb",
    "load_to_marker_array",
    "load_to_model_v",
    "load_to_scene",
    "load_to_scene_update",
    "load_to_shapes",
    "load_to_tree_viewer",
    "point_cloud2_to_point_cloud",
    "point_cloud_to_point_cloud2",
    "pose_array_to_draw",
]
