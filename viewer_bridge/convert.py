"""Pure converters: one Drake LCM message in, one target message out, in one call each.

Every function here takes the bytes of one message (as LCM, `lcm-logger` or a ROS 2 subscriber
gives them) and returns bytes or plain objects: ROS 2 messages as CDR bytes (`TypedCdr`, name and
CDR, where one call gives messages of several types), protobuf messages as bytes. None of them
keeps state between calls or does I/O (except reading a mesh file a target must carry as
triangles). Importing this module imports none of their code: each function imports its codecs
on its first call, so `import viewer_bridge.convert` loads no numpy, pydantic, yaml, protobuf
or PIL, and compiles no codec. Options are keyword-only parameters, so a misspelt option is a
`TypeError`; an option left at `None` keeps the default of the format's table (`mappings/`).
Units are SI (metres, seconds; stamps are (sec, nanosec)), quaternions w-first as in Drake;
each function says which frame its output is in.

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
from typing import TYPE_CHECKING, Any, Literal

# Light at import: these three name defaults and results and import nothing. Everything else is
# imported by the function that needs it, so that `import viewer_bridge.convert` loads no numpy,
# pydantic, yaml, protobuf or PIL and compiles no codec (tests/test_import.py holds it to that).
from viewer_bridge.formats.ros.message_types import WORLD, TypedCdr
from viewer_bridge.formats.tree_viewer.common import DEFAULT_PREFIX, JsonObject

if TYPE_CHECKING:
    from viewer_bridge.lcmcodec.codegen import Buffer
    from viewer_bridge.model.image import Image
    from viewer_bridge.model.scene import LinkPoses, Scene

# --- reading Drake's messages --------------------------------------------------------------------
#
# Units and frames throughout: metres, seconds (stamps as (sec, nanosec) pairs), quaternions
# w-first as Drake writes them; a draw's poses are each link's in the world frame, a load's
# geometry poses each in its link's frame.


def draw_to_link_poses(data: Buffer) -> LinkPoses:
    """An `lcmt_viewer_draw` as arrays: link names, robot numbers, positions N x 3 (metres,
    world frame), w-first quaternions N x 4 and the draw's sim time (`timestamp_ms`).

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_draw`, naming the field and offset.
    """
    from viewer_bridge.formats.drake.draw import DrawDecoder

    return DrawDecoder().decode(data)


def load_to_scene(data: Buffer, *, draw: Buffer | None = None) -> Scene:
    """An `lcmt_viewer_load_robot` as the scene model (geometry in metres, each posed in its
    link's frame), its links placed in the world frame by `draw` when given.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_load_robot` (or, for `draw`, no draw), naming the field
            and offset.
    """
    from viewer_bridge.formats.drake.load import decode_load

    scene = decode_load(data)
    return scene if draw is None else scene.with_poses(draw_to_link_poses(draw))


# --- a draw (every link's pose) ------------------------------------------------------------------


def draw_to_pose_array(data: bytes, *, frame_id: str = WORLD) -> bytes:
    """A draw as `geometry_msgs/PoseArray` CDR: one pose per link in the draw's order, in metres
    in the frame `frame_id`, stamped with the draw's sim time.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_draw`, naming the field and offset.
        EncodeError: a `frame_id` a CDR string cannot carry (a NUL), or a sim time past int32 seconds.
    """
    from viewer_bridge.formats.ros.poses import PoseArrayEncoder

    return PoseArrayEncoder(frame_id).encode(draw_to_link_poses(data))


def draw_to_tf(
    data: bytes, *, world_frame: str = WORLD, frame_prefix: str = "", stamp: tuple[int, int] | None = None
) -> bytes:
    """A draw as `tf2_msgs/TFMessage` CDR: `world_frame` -> every link (metres), frames named as
    in the field (`plant::iiwa::link_0` -> `frame_prefix` + `plant/iiwa/link_0`). `stamp` is
    (sec, nanosec); None: the draw's sim time.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_draw`, naming the field and offset.
        EncodeError: a frame name a CDR string cannot carry (a NUL), or a sim time past int32 seconds.
    """
    from viewer_bridge.formats.ros.cdr import time_parts
    from viewer_bridge.formats.ros.tf import FrameNames, TransformsEncoder

    poses = draw_to_link_poses(data)
    encoder = TransformsEncoder(FrameNames(world_frame, frame_prefix))
    return encoder.encode(poses, stamp or time_parts(poses.timestamp_ms))


def draw_to_pose_v(data: bytes, *, message: Literal["Pose_V", "PosesStamped"] = "Pose_V") -> bytes:
    """A draw as ign/gz `Pose_V` bytes (or the legacy `PosesStamped`): a Pose per link named as
    in the draw, in metres in the world frame, stamped with the draw's sim time.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_draw`, naming the field and offset.
    """
    from viewer_bridge.formats.ign.poses import PosesEncoder

    return PosesEncoder(message).encode(draw_to_link_poses(data))


def draw_to_tree_viewer(data: bytes, *, prefix: Sequence[str] = DEFAULT_PREFIX) -> JsonObject:
    """A draw as the request Director's tree viewer is sent: a `settransform` per link at
    `[*prefix, robot_num, link name]`, translation in metres and w-first quaternion relative to
    the tree's root, numbers rounded to 8 decimals. `envelope.encode` of it
    (`viewer_bridge.formats.tree_viewer.envelope`) is the `viewer2_comms_t` to publish.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_draw`, naming the field and offset.
    """
    from viewer_bridge.formats.tree_viewer.requests import draw_request

    return draw_request(draw_to_link_poses(data), prefix)


def draw_to_frame_transforms(
    data: bytes, *, world_frame: str = WORLD, frame_prefix: str = "", stamp: tuple[int, int] | None = None
) -> bytes:
    """A draw as `foxglove.FrameTransforms` protobuf bytes, framed, in metres and stamped as
    `draw_to_tf` frames and stamps it.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_draw`, naming the field and offset.
    """
    from viewer_bridge.formats.foxglove.transforms import FrameTransformsEncoder
    from viewer_bridge.formats.ros.tf import FrameNames
    from viewer_bridge.model.sim_time import sec_nsec_from_ms

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
    """A load as `visualization_msgs/MarkerArray` CDR (DELETEALL first), in metres in the frame
    `frame_id` (None: the table's, `world`), each marker placed by `draw` (without one, at its
    link's origin). `embed_mesh_files`: mesh files as triangle lists, for an RViz that cannot
    read them; `point_size`: metres, for point clouds.

    Raises:
        DecodeError: bytes that are no load (or, for `draw`, no draw), naming the field and offset.
    """
    from viewer_bridge.formats.ros.markers import marker_array_cdr

    options = _given(frame_id=frame_id, embed_mesh_files=embed_mesh_files, point_size=point_size)
    return marker_array_cdr(load_to_scene(data, draw=draw), options)


def load_to_shapes(data: bytes) -> list[TypedCdr]:
    """A load as shape_msgs CDR, one message per geometry, in metres in its link's frame: each a
    `TypedCdr` whose `type` is `shape_msgs/msg/SolidPrimitive`, `Mesh` or `Plane`.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_load_robot`, naming the field and offset.
    """
    from viewer_bridge.formats.drake.load import decode_load
    from viewer_bridge.formats.ros.shapes import shapes_cdr

    return shapes_cdr(decode_load(data))


def load_to_model_v(data: bytes, *, draw: bytes | None = None) -> bytes:
    """A load as ign/gz `Model_V` bytes: a Model per robot_num, a Link per Drake link (posed in
    the world frame by `draw`, else at the origin), a Visual per geometry in its link's frame;
    metres.

    Raises:
        DecodeError: bytes that are no load (or, for `draw`, no draw), naming the field and offset.
    """
    from viewer_bridge.formats.ign.model import model_v_bytes

    return model_v_bytes(load_to_scene(data, draw=draw))


def load_to_scene_update(
    data: bytes, *, world_frame: str = WORLD, frame_prefix: str = "", stamp: tuple[int, int] = (0, 0)
) -> bytes:
    """A load as `foxglove.SceneUpdate` protobuf bytes: an entity per link, in metres in its
    link's frame (named as `draw_to_tf` names them), stamped `stamp` (sec, nanosec). Needs the
    `foxglove` extra.

    Raises:
        DecodeError: bytes that are no `lcmt_viewer_load_robot`, naming the field and offset.
        MissingExtra: the `foxglove` extra is not installed.
    """
    from viewer_bridge.formats.drake.load import decode_load
    from viewer_bridge.formats.ros.tf import FrameNames
    from viewer_bridge.util.extras import missing

    try:
        from viewer_bridge.formats.foxglove.scene import scene_update
    except ImportError as error:
        raise missing(error, "load_to_scene_update") from None
    update = scene_update(decode_load(data), FrameNames(world_frame, frame_prefix), stamp)
    return bytes(update.SerializeToString())


def load_to_glb(data: bytes, *, draw: bytes | None = None) -> bytes:
    """A load as a binary glTF 2.0 (`.glb`) document, every shape as triangles, posed by `draw`
    (else each link at the origin); metres, in Drake's world frame as it is (z up: no axes are
    swapped for glTF's y-up convention).

    Raises:
        DecodeError: bytes that are no load (or, for `draw`, no draw), naming the field and offset.
    """
    from viewer_bridge.formats.gltf import write_gltf

    return write_gltf(load_to_scene(data, draw=draw), binary=True)


def load_to_tree_viewer(
    data: bytes, *, draw: bytes | None = None, prefix: Sequence[str] = DEFAULT_PREFIX
) -> list[JsonObject]:
    """A load as the two requests Director's tree viewer is sent: delete the tree under
    `prefix`, then a `setgeometry` per geometry in its link's frame (and a `settransform` per
    link of `draw`); metres.

    Raises:
        DecodeError: bytes that are no load (or, for `draw`, no draw), naming the field and offset.
    """
    from viewer_bridge.formats.tree_viewer.requests import load_requests

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
    """An `lcmt_contact_results_for_viz` as MarkerArray CDR in the world frame `frame_id`, as
    meldis draws it: force arrows (`force_scale` metres per newton) and moment arrows
    (`moment_scale` metres per newton metre) of `arrow_radius` metres, none shorter than
    `min_length` metres, hydroelastic surfaces coloured over `pressure_range` (pascals). None:
    the default of `viewer_bridge.model.contact.ContactDrawOptions`.

    Raises:
        DecodeError: bytes that are no `lcmt_contact_results_for_viz`, naming the field and offset.
        InvalidSetting: an option out of its range (a scale that is not positive...).
    """
    from pydantic import ValidationError

    from viewer_bridge.errors import InvalidSetting
    from viewer_bridge.formats.drake.contact import decode_contact_results
    from viewer_bridge.formats.ros.contact import contact_marker_array_cdr
    from viewer_bridge.model.contact import ContactDrawOptions

    given = _given(
        force_scale=force_scale,
        moment_scale=moment_scale,
        arrow_radius=arrow_radius,
        min_length=min_length,
        pressure_range=pressure_range,
        surfaces=surfaces,
    )
    try:
        drawing = ContactDrawOptions(**given)
    except ValidationError as error:
        raise InvalidSetting(f"contacts_to_marker_array: {error}") from None
    return contact_marker_array_cdr(decode_contact_results(data), drawing, _given(frame_id=frame_id))


def point_cloud_to_point_cloud2(data: bytes, *, frame_id: str = WORLD) -> bytes:
    """An `lcmt_point_cloud` as `sensor_msgs/PointCloud2` CDR, points in metres in the cloud's
    own frame; `frame_id` for a cloud without one.

    Raises:
        DecodeError: bytes that are no `lcmt_point_cloud`, naming the field and offset.
        EncodeError: a sim time past int32 seconds, which `builtin_interfaces/Time` cannot hold.
    """
    from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm
    from viewer_bridge.formats.ros.point_cloud import cloud_to_cdr

    return cloud_to_cdr(cloud_from_lcm(data), frame_id)


def point_cloud2_to_point_cloud(data: bytes) -> bytes:
    """A `sensor_msgs/PointCloud2` (x, y, z in metres, optional normals and rgb) as an
    `lcmt_point_cloud` in the same frame.

    Raises:
        DecodeError: bytes that are no PointCloud2 this function reads, naming the field and offset.
    """
    from viewer_bridge.formats.drake.point_cloud import cloud_to_lcm
    from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr

    return cloud_to_lcm(cloud_from_cdr(data))


def image_array_to_images(data: bytes) -> list[Image]:
    """An `lcmt_image_array` as images whose `pixels` are numpy arrays (height x width x
    channels), decompressed, in Drake's units (depth in millimetres as uint16 or metres as
    float32); named by Drake's port (`rgb`, `depth`, `label`), `time_us` their sim time.

    Raises:
        DecodeError: bytes that are no `lcmt_image_array`, naming the field and offset. An image that does not
            decompress or decode is one too.
    """
    from viewer_bridge.formats.drake.image import read_image_array, unpack

    return [unpack(packed) for packed in read_image_array(data).images]


def image_array_to_ros_images(
    data: bytes,
    *,
    frame_id: str = "camera",
    drop_alpha: bool = False,
    depth: Literal["16UC1", "32FC1"] = "16UC1",
) -> dict[str, bytes]:
    """An `lcmt_image_array` as `sensor_msgs/Image` CDR per image name, in the camera frame
    `frame_id`, stamped with its sim time.

    `drop_alpha`: rgba8 -> rgb8; `depth`: `16UC1` keeps millimetres, `32FC1` writes depth in
    metres (REP 117), as a float depth image always is.

    Raises:
        DecodeError: bytes that are no `lcmt_image_array`, naming the field and offset. An image that does not
            decompress or decode is one too.
        EncodeError: a sim time past int32 seconds, which `builtin_interfaces/Time` cannot hold.
    """
    from viewer_bridge.formats.ros.cdr import time_parts_from_us
    from viewer_bridge.formats.ros.image import image_to_cdr
    from viewer_bridge.model.image import Layout, depth_rep117

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
    """A `geometry_msgs/PoseArray` (metres, read as the world frame whatever its `frame_id`) as
    an `lcmt_viewer_draw`. PoseArray has no names: they come from `link_names` (with
    `robot_nums`, else 0), else from `load`'s links in order but for `world` (whose pose a draw
    leaves out, as Drake's does), else `pose_0`, `pose_1`, ... `SceneError` when their count
    differs from the poses'.

    Raises:
        DecodeError: bytes that are no PoseArray (or, for `load`, no load).
        SceneError: as many link names as poses were not given.
        EncodeError: a pose an `lcmt_viewer_draw` cannot hold.
    """
    from viewer_bridge.errors import SceneError
    from viewer_bridge.formats.drake.draw import DrawEncoder
    from viewer_bridge.formats.drake.load import decode_load
    from viewer_bridge.formats.ros.poses import pose_array_arrays, poses_from_pose_array_cdr

    count = pose_array_arrays(data)[2].shape[0]
    if link_names is None and load is not None:
        links = [link for link in decode_load(load).links if link.name != WORLD]
        link_names = [link.name for link in links]
        robot_nums = [link.robot_num for link in links] if robot_nums is None else robot_nums
    names = [f"pose_{index}" for index in range(count)] if link_names is None else list(link_names)
    if len(names) != count:
        raise SceneError(f"the PoseArray has {count} poses, {len(names)} link names given")
    return DrawEncoder().encode(poses_from_pose_array_cdr(data, names, robot_nums))


def cdr_to_rclpy(data: bytes, typename: str) -> object:
    """ROS 2 CDR as the rclpy message object of `typename` (`geometry_msgs/msg/PoseArray`).
    Needs the `ros` extra (rclpy and the message packages).

    Raises:
        MissingExtra: rclpy or the message's package is not installed.
        UnknownName: the package has no message `typename` names (a `KeyError` too).
        DecodeError: bytes that are no CDR of `typename`.
    """
    from viewer_bridge.errors import DecodeError, UnknownName
    from viewer_bridge.util.extras import require

    serialization = require("rclpy.serialization", "cdr_to_rclpy")
    package, _, name = typename.rpartition("/msg/") if "/msg/" in typename else typename.partition("/")
    messages = require(f"{package}.msg", "cdr_to_rclpy")
    message_class = getattr(messages, name, None)
    if not isinstance(message_class, type):
        known = sorted(
            f"{package}/msg/{known}" for known, value in vars(messages).items() if isinstance(value, type)
        )
        raise UnknownName("ROS 2 message type", typename, known)
    try:
        return serialization.deserialize_message(data, message_class)
    except RuntimeError as error:  # rclpy's RMWError: the bytes are no CDR of this type
        reason = str(error).split(", at /")[0]  # without the C++ source location rclpy appends
        raise DecodeError(typename, "<message>", 0, reason) from None


def _given(**options: Any) -> dict[str, Any]:
    """The options set (not None): what overrides a table's or a model's defaults."""
    return {name: value for name, value in options.items() if value is not None}


__all__ = [
    "JsonObject",
    "TypedCdr",
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
