"""Drake's LCM scene to ROS 2 (and a PoseArray back): one class per message pair."""

from __future__ import annotations

from typing import Any

from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import link_from_lcm
from viewer_bridge.formats.ros.cdr import U32, time_parts, time_parts_from_us
from viewer_bridge.formats.ros.markers import MarkerStream, marker_array_cdr
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY, MESH, PLANE, POSE_ARRAY, SOLID_PRIMITIVE
from viewer_bridge.formats.ros.poses import PoseArrayEncoder, pose_array_arrays, poses_from_pose_array_cdr
from viewer_bridge.formats.ros.shapes import shapes_cdr
from viewer_bridge.lcmcodec.codecs import LINK_DATA
from viewer_bridge.lcmcodec.codegen import CDR_LE
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.scene import Scene
from viewer_bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from viewer_bridge.translators.drake_stream import DrakeTranslator, DrawReader, PerLoadTranslator
from viewer_bridge.translators.options import MarkerOptions, StampOptions
from viewer_bridge.translators.types import DRAW_TYPE, LINK_DATA_TYPE, LOAD_TYPE, ros_type
from viewer_bridge.transports.base import LCM, MessageType, Received

_CLOCK = "rosgraph_msgs/msg/Clock"
_BYTES = "std_msgs/msg/UInt8MultiArray"


class DrakeToMarkerArray(DrakeTranslator):
    """load + draw -> `visualization_msgs/MarkerArray`: the load's array (DELETEALL first), then
    each draw re-poses the markers (a CDR template, see `MarkerStream`). Latched, so a late
    RViz gets the last full array."""

    Options = MarkerOptions
    options: MarkerOptions
    outputs = (Output("", ros_type(MARKER_ARRAY), latched=True),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.markers: MarkerStream | None = None

    def translate(self, message: Received) -> Outputs:
        scene, poses = self.drake.read(message)
        out: Outputs = []
        if scene is not None:
            self.markers = MarkerStream(scene, self.options.table_overrides())
            out.append((0, self.markers.load_cdr))
        if poses is not None and self.markers is not None:
            out.append((0, self.markers.update(poses)))
        return out


class PoseArrayOptions(StampOptions):
    frame_id: str = "world"


class DrakeToPoseArray(DrawReader):
    """draw -> `geometry_msgs/PoseArray` (in the draw's link order), from the arrays."""

    Options = PoseArrayOptions
    options: PoseArrayOptions
    reads = (DRAW_TYPE,)
    outputs = (Output("", ros_type(POSE_ARRAY)),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.encoder = PoseArrayEncoder(self.options.frame_id)

    def translate(self, message: Received) -> Outputs:
        poses = self.draw_poses(message)  # needs no load
        sim = self.options.sim_stamps(self.shared.clock)
        # its receive time as /tf has it unless the bridge's clock is sim (None: the draw's sim time)
        return [(0, self.encoder.encode(poses, None if sim else time_parts_from_us(message.received_us)))]


class DrakeToClock(DrawReader):
    """draw -> `rosgraph_msgs/Clock` with Drake's sim time, for nodes with `use_sim_time` (the
    config's `time: sim` makes a route of it to `/clock`: `viewer_bridge.config.bridge`)."""

    reads = (DRAW_TYPE,)
    outputs = (Output("", ros_type(_CLOCK)),)

    def translate(self, message: Received) -> Outputs:
        stamp = time_parts(self.draw_poses(message).timestamp_ms)
        return [(0, ros_writer(_CLOCK).write((stamp,)))]


class DrakeToShapes(PerLoadTranslator):
    """load -> one shape_msgs message per geometry: SolidPrimitive, Mesh or Plane on
    `<name>/primitives`, `<name>/meshes`, `<name>/planes`. Latched (give the route a depth as
    large as the scene's geometry count)."""

    reads = (LOAD_TYPE,)
    outputs = (
        Output("/primitives", ros_type(SOLID_PRIMITIVE), latched=True),
        Output("/meshes", ros_type(MESH), latched=True),
        Output("/planes", ros_type(PLANE), latched=True),
    )
    _INDEX = {SOLID_PRIMITIVE: 0, MESH: 1, PLANE: 2}

    def on_scene(self, scene: Scene, channel: str) -> Outputs:
        return [(self._INDEX[typename], data) for typename, data in shapes_cdr(scene)]


class DrakeLinkToMarkerArray(Translator):
    """`lcmt_viewer_link_data` (DRAKE_VIEWER_DEFORMABLE: world-frame meshes, every frame) ->
    MarkerArray, ids stable from frame to frame."""

    Options = MarkerOptions
    options: MarkerOptions
    reads = (LINK_DATA_TYPE,)
    outputs = (Output("", ros_type(MARKER_ARRAY)),)

    def translate(self, message: Received) -> Outputs:
        link = link_from_lcm(LINK_DATA.strict.decode(message.data))
        scene = Scene((link,))
        return [(0, marker_array_cdr(scene, self.options.table_overrides(), delete_all=False))]


class PoseArrayToDrawOptions(TranslatorOptions):
    """PoseArray has no names: they come from `link_names` (else `pose_0`, `pose_1`, ...)."""

    link_names: list[str] | None = None
    robot_nums: list[int] | None = None


class RosPoseArrayToDrakeDraw(Translator):
    """`geometry_msgs/PoseArray` -> `lcmt_viewer_draw`, names and robot_nums from the options."""

    Options = PoseArrayToDrawOptions
    options: PoseArrayToDrawOptions
    reads = (ros_type(POSE_ARRAY),)
    outputs = (Output("", DRAW_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.encoder = DrawEncoder()

    def translate(self, message: Received) -> Outputs:
        data = message.data
        count = pose_array_arrays(data)[2].shape[0]
        names = self.options.link_names or [f"pose_{index}" for index in range(count)]
        poses = poses_from_pose_array_cdr(data, names, self.options.robot_nums)
        return [(0, self.encoder.encode(poses))]


class LcmBytesToRos(Translator):
    """Any LCM message -> its bytes in a `std_msgs/UInt8MultiArray`: no translation at all,
    the baseline the benchmarks measure the translators against."""

    reads = (MessageType("*", LCM),)
    outputs = (Output("", ros_type(_BYTES)),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # Everything before the data's count (no dimensions, offset 0), where the writer marks it.
        empty, marks = ros_writer(_BYTES, ("data",)).write_marked((([], 0), b""))
        self._head = empty[: len(CDR_LE) + marks["data"][0]]

    def translate(self, message: Received) -> Outputs:
        data = message.data
        return [(0, self._head + U32.pack(len(data)) + data)]
