"""The router's translators: one class per (source message, target message) pair.

A translator takes the bytes of one source message and returns the bytes of what to publish,
per output. It keeps what it must between messages (the decoded scene of the last load, the
marker template), so the formats stay pure functions. Which translator a route uses is named in
its config; `TRANSLATORS` is the registry.

Drake's scene arrives as two streams (a load now and then, a draw every frame), told apart by
the message's fingerprint, not its channel. `LoadCache` keeps the last load per load channel for
every route (and, with a folder, across runs): a translator that gets a draw for a scene it has
not seen takes the load from there.
"""

from __future__ import annotations

import os
import re
import struct
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from bridge.errors import DecodeError, SceneError
from bridge.formats import ign, ros, tree_viewer
from bridge.formats.drake import DrawDecoder, DrawEncoder, decode_load, link_from_lcm
from bridge.formats.ros_messages import time_parts
from bridge.lcmcodec import DRAW, LINK_DATA, LOAD_ROBOT, VIEWER2_COMMS
from bridge.scene import LinkPoses, Scene


@dataclass(frozen=True, slots=True)
class Output:
    """One thing a translator publishes: the name suffix, the message type, and if it is latched."""

    suffix: str
    typename: str
    latched: bool = False


Outputs = list[tuple[int, bytes]]  # (index into `outputs`, payload)


class LoadCache:
    """The last `lcmt_viewer_load_robot` bytes seen per load channel, shared by every route.

    With a folder, loads are also written there (one file per channel) and read back at start,
    so a bridge restarted while the simulation runs still has the model: Drake sends a load
    only when the geometry changes.
    """

    def __init__(self, folder: str | Path | None = None) -> None:
        self._loads: dict[str, bytes] = {}
        self._lock = threading.Lock()
        self._folder = Path(folder).expanduser() if folder else None
        if self._folder is not None and self._folder.is_dir():
            for path in self._folder.glob("*.lcm"):
                self._loads[path.stem] = path.read_bytes()

    def put(self, channel: str, data: bytes) -> None:
        # Under the lock, file and memory change together: routes putting the same channel's
        # loads cannot leave an older one on disk than in memory.
        with self._lock:
            if self._loads.get(channel) == data:
                return
            self._loads[channel] = data
            if self._folder is not None and re.fullmatch(r"[A-Za-z0-9_.<>-]+", channel):
                self._folder.mkdir(parents=True, exist_ok=True)
                with tempfile.NamedTemporaryFile(dir=self._folder, delete=False) as file:
                    file.write(data)
                os.replace(file.name, self._folder / f"{channel}.lcm")

    def get(self, channel: str) -> bytes | None:
        with self._lock:
            return self._loads.get(channel)


def load_channel_for(draw_channel: str) -> str:
    """`DRAKE_VIEWER_DRAW_PROXIMITY` -> `DRAKE_VIEWER_LOAD_ROBOT_PROXIMITY` (same prefix and suffix)."""
    return draw_channel.replace("DRAKE_VIEWER_DRAW", "DRAKE_VIEWER_LOAD_ROBOT", 1)


Reply = Callable[[str, bytes], None]  # publish on the source's transport: (channel, bytes)


def _no_reply(channel: str, data: bytes) -> None:
    raise OSError(f"this route cannot answer on {channel}")


class Translator:
    """Base of every translator: what it reads and writes, and one call per message.

    `reply` publishes back on the source's transport (the router sets it): how a protocol
    with requests and responses, like the tree viewer's, answers.
    """

    source: ClassVar[str]  # "lcm" or "ros"
    destination: ClassVar[str]
    source_type: str = ""  # the message type a ros or ign source subscribes to
    outputs: tuple[Output, ...]  # a class attribute; an instance may set its own

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        self.options = options
        self.loads = loads
        self.reply: Reply = _no_reply

    def translate(self, channel: str, data: bytes) -> Outputs:
        raise NotImplementedError


class DrakeSceneTranslator(Translator):
    """Reads Drake's load and draw messages into a scene; subclasses say what to publish."""

    source = "lcm"
    destination = "ros"

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.decoder = DrawDecoder()
        self.scene: Scene | None = None
        self._load_bytes = b""
        self._link_names: frozenset[str] = frozenset()

    def translate(self, channel: str, data: bytes) -> Outputs:
        fingerprint = data[:8]
        if fingerprint == LOAD_ROBOT.packed_fingerprint:
            self.loads.put(channel, data)
            return self._load(data)
        if fingerprint == DRAW.packed_fingerprint:
            poses = self.decoder.decode(data)
            out: Outputs = []
            if not self._link_names.issuperset(poses.names):  # a scene this route has not seen
                cached = self.loads.get(load_channel_for(channel))
                if cached is not None:
                    out += self._load(cached)
            return out + self.on_draw(poses)
        raise DecodeError(
            "drake viewer message", "", 0, f"fingerprint {fingerprint.hex()} is not a load or a draw"
        )

    def _load(self, data: bytes) -> Outputs:
        if data == self._load_bytes:  # re-sent unchanged (e.g. for late listeners): nothing new
            return []
        self.scene = decode_load(data)
        self._load_bytes = data
        self._link_names = frozenset(link.name for link in self.scene.links)
        return self.on_load(self.scene)

    def on_load(self, scene: Scene) -> Outputs:
        return []

    def on_draw(self, poses: LinkPoses) -> Outputs:
        return []


class DrakeToMarkerArray(DrakeSceneTranslator):
    """load + draw -> `visualization_msgs/MarkerArray`: the load's array (DELETEALL first), then
    each draw re-poses the markers (a CDR template, see `ros.MarkerStream`). Latched, so a late
    RViz gets the last full array."""

    outputs = (Output("", ros.MARKER_ARRAY, latched=True),)

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.stream: ros.MarkerStream | None = None

    def on_load(self, scene: Scene) -> Outputs:
        self.stream = ros.MarkerStream(scene, self.options)
        return [(0, self.stream.load_cdr)]

    def on_draw(self, poses: LinkPoses) -> Outputs:
        return [] if self.stream is None else [(0, self.stream.update(poses))]


class DrakeToPoseArray(DrakeSceneTranslator):
    """draw -> `geometry_msgs/PoseArray` (in the draw's link order), from the arrays."""

    outputs = (Output("", ros.POSE_ARRAY),)

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.encoder = ros.PoseArrayEncoder(str(options.get("frame_id", "world")))

    def translate(self, channel: str, data: bytes) -> Outputs:
        return [(0, self.encoder.encode(self.decoder.decode(data)))]  # needs no load


class DrakeToClock(DrakeSceneTranslator):
    """draw -> `rosgraph_msgs/Clock` with Drake's sim time, for nodes with `use_sim_time`."""

    outputs = (Output("", "rosgraph_msgs/msg/Clock"),)
    _CLOCK = struct.Struct("<4siI")

    def translate(self, channel: str, data: bytes) -> Outputs:
        seconds, nanoseconds = time_parts(self.decoder.decode(data).timestamp_ms)
        return [(0, self._CLOCK.pack(b"\x00\x01\x00\x00", seconds, nanoseconds))]


class DrakeToShapes(DrakeSceneTranslator):
    """load -> one shape_msgs message per geometry: SolidPrimitive, Mesh or Plane on
    `<name>/primitives`, `<name>/meshes`, `<name>/planes`. Latched (give the route a depth as
    large as the scene's geometry count)."""

    outputs = (
        Output("/primitives", ros.SOLID_PRIMITIVE, latched=True),
        Output("/meshes", ros.MESH, latched=True),
        Output("/planes", ros.PLANE, latched=True),
    )
    _INDEX: ClassVar[dict[str, int]] = {ros.SOLID_PRIMITIVE: 0, ros.MESH: 1, ros.PLANE: 2}

    def on_load(self, scene: Scene) -> Outputs:
        return [(self._INDEX[posed.typename], ros.to_cdr(posed.shape)) for posed in ros.shapes(scene)]


class DrakeLinkToMarkerArray(Translator):
    """`lcmt_viewer_link_data` (DRAKE_VIEWER_DEFORMABLE: world-frame meshes, every frame) ->
    MarkerArray, ids stable from frame to frame."""

    source = "lcm"
    destination = "ros"
    outputs = (Output("", ros.MARKER_ARRAY),)

    def translate(self, channel: str, data: bytes) -> Outputs:
        link = link_from_lcm(LINK_DATA.decode(data))
        return [(0, ros.marker_array_cdr(Scene((link,)), self.options, delete_all=False))]


class RosPoseArrayToDrakeDraw(Translator):
    """`geometry_msgs/PoseArray` -> `lcmt_viewer_draw`. PoseArray has no names: they come from
    the option `link_names` (and `robot_nums`), or are `pose_0`, `pose_1`, ..."""

    source = "ros"
    destination = "lcm"
    source_type = ros.POSE_ARRAY
    outputs = (Output("", DRAW.type_name),)

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.encoder = DrawEncoder()

    def translate(self, channel: str, data: bytes) -> Outputs:
        count = ros.pose_array_arrays(data)[2].shape[0]
        names: Sequence[str] = self.options.get("link_names") or [f"pose_{index}" for index in range(count)]
        robot_nums = self.options.get("robot_nums")
        return [(0, self.encoder.encode(ros.poses_from_pose_array_cdr(data, names, robot_nums)))]


class TreeViewerServer(Translator):
    """Director's tree viewer, served: requests on `DIRECTOR_TREE_VIEWER_REQUEST_<id>` -> a tree per
    client, answered on `DIRECTOR_TREE_VIEWER_RESPONSE_<id>`, and the tree as a MarkerArray.

    Every request gets exactly one reply: 0, 1 (MISSING_PATHS), -1 (format, listing the one we
    speak), -2 (version), -3 (bad request, or not an envelope at all), -4 (unknown command).
    Options: `mesh_roots` (folders mesh_file paths may be in), the marker table's options.
    """

    source = "lcm"
    destination = "ros"
    outputs = (Output("", ros.MARKER_ARRAY, latched=True),)
    _CLIENT = re.compile(r"DIRECTOR_TREE_VIEWER_REQUEST_<([^<>]*)>")

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.trees: dict[str, tree_viewer.TreeState] = {}

    def translate(self, channel: str, data: bytes) -> Outputs:
        match = self._CLIENT.fullmatch(channel)
        if match is None:
            raise DecodeError(
                VIEWER2_COMMS.type_name, "", 0, f"{channel} is not a tree viewer request channel"
            )
        client = match.group(1)
        state = self.trees.setdefault(client, tree_viewer.TreeState(self.options.get("mesh_roots", ())))
        answer = tree_viewer.response_channel(client)
        try:
            response, changed = self._respond(state, data)
        except Exception as error:  # a bug of ours: still answer, then let the router count it
            self.reply(
                answer,
                tree_viewer.encode({"status": tree_viewer.ERROR_HANDLING_REQUEST, "error": repr(error)}),
            )
            raise
        self.reply(answer, tree_viewer.encode(response))
        if response["status"] not in (tree_viewer.OK, tree_viewer.MISSING_PATHS):
            raise tree_viewer.RequestRejected(response["status"], f"client {client}: {response['error']}")
        marker_options = {key: value for key, value in self.options.items() if key != "mesh_roots"}
        return [(0, ros.marker_array_cdr(state.scene(), marker_options, delete_all=changed))]

    @staticmethod
    def _respond(state: tree_viewer.TreeState, data: bytes) -> tuple[dict[str, Any], bool]:
        """The response to one envelope, and whether the tree's geometry changed."""
        try:
            request = tree_viewer.decode(data)
        except tree_viewer.RequestError as error:
            response: dict[str, Any] = {"status": error.status, "error": error.reason}
            if error.status == tree_viewer.ERROR_UNKNOWN_FORMAT:
                response["supported_formats"] = {tree_viewer.FORMAT: [list(tree_viewer.VERSION)]}
            return response, False
        except DecodeError as error:
            return {"status": tree_viewer.ERROR_HANDLING_REQUEST, "error": str(error)}, False
        changed = bool(request.get("setgeometry") or request.get("delete"))
        return state.respond(request), changed


class DrakeToTreeViewer(DrakeSceneTranslator):
    """Drake load/draw -> tree viewer requests for a running Director (the client side).

    Route the client's response channel to it as well: on MISSING_PATHS it re-sends the geometry
    and transforms under the missing paths; on -1 or -2 (the viewer does not speak our format)
    it says so and stops sending. Options: `prefix` (default ["drake"]).
    """

    destination = "lcm"
    outputs = (Output("", VIEWER2_COMMS.type_name),)

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.prefix = tuple(options.get("prefix", tree_viewer.DEFAULT_PREFIX))
        self.refused: str | None = None
        self.poses: LinkPoses | None = None

    def translate(self, channel: str, data: bytes) -> Outputs:
        if self.refused is not None:
            raise SceneError(self.refused)
        if data[:8] == VIEWER2_COMMS.packed_fingerprint:
            return self._on_response(tree_viewer.decode(data))
        return super().translate(channel, data)

    def on_load(self, scene: Scene) -> Outputs:
        return [(0, tree_viewer.encode(request)) for request in tree_viewer.load_requests(scene, self.prefix)]

    def on_draw(self, poses: LinkPoses) -> Outputs:
        self.poses = poses
        return [(0, tree_viewer.encode(tree_viewer.draw_request(poses, self.prefix)))]

    def _on_response(self, response: dict[str, Any]) -> Outputs:
        status = response.get("status")
        if status in (tree_viewer.ERROR_UNKNOWN_FORMAT, tree_viewer.ERROR_UNKNOWN_FORMAT_VERSION):
            self.refused = (
                f"the viewer refused {tree_viewer.FORMAT} {tree_viewer.VERSION[0]}.{tree_viewer.VERSION[1]} "
                f"(status {status}: {response.get('error', 'no reason given')}); no longer sending to it"
            )
            raise SceneError(self.refused)
        if status != tree_viewer.MISSING_PATHS or self.scene is None:
            return []
        missing = [tuple(path) for path in response.get("missing_paths", []) if isinstance(path, list)]
        links = tuple(
            link
            for link in self.scene.links
            if any(_related(tuple(tree_viewer.link_path(link, self.prefix)), path) for path in missing)
        )
        if not links:
            return []
        partial = Scene(links, self.poses)
        request = tree_viewer.load_requests(partial, self.prefix)[1]  # setgeometry (+ transforms), no delete
        return [(0, tree_viewer.encode(request))]


def _related(link_path: tuple[str, ...], missing: tuple[Any, ...]) -> bool:
    """Whether a link lies under a missing path, or the missing path under the link."""
    shorter = min(len(link_path), len(missing))
    return link_path[:shorter] == tuple(missing[:shorter])


class _DrakeToIgn(DrakeSceneTranslator):
    """Base of Drake -> ign-transport: `options.package` `ignition` (default, ign-msgs 8 as
    Debian's tools speak) or `gz` picks the message names."""

    destination = "ign"
    message_name: ClassVar[str]

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        package = options.get("package", "ignition")
        if package not in ("ignition", "gz"):
            raise SceneError(f"options.package must be 'ignition' or 'gz', not {package!r}")
        self.msgs = ign.IGNITION if package == "ignition" else ign.GZ
        self.outputs = (Output("", self.msgs.full_name(self.message_name), latched=True),)


class DrakeToIgnModel(_DrakeToIgn):
    """load -> `Model` (every link of the scene). ign-transport has no latching, so the model is
    published again every `options.republish_s` seconds (default 1) while draws flow, for
    subscribers that start late; its link poses follow the latest draw."""

    message_name = "Model"

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.republish_s = float(options.get("republish_s", 1.0))
        self._published_at = float("-inf")

    def build(self, scene: Scene) -> bytes:
        return bytes(ign.model(scene, msgs=self.msgs).SerializeToString())

    def on_load(self, scene: Scene) -> Outputs:
        self._published_at = time.monotonic()
        return [(0, self.build(scene))]

    def on_draw(self, poses: LinkPoses) -> Outputs:
        if self.scene is None or time.monotonic() - self._published_at < self.republish_s:
            return []
        self._published_at = time.monotonic()
        return [(0, self.build(self.scene.with_poses(poses)))]


class DrakeToIgnModelV(DrakeToIgnModel):
    """load -> `Model_V`: a Model per robot_num (model instance); republished like the Model."""

    message_name = "Model_V"

    def build(self, scene: Scene) -> bytes:
        return bytes(ign.model_v(scene, msgs=self.msgs).SerializeToString())


class DrakeToIgnPoseV(_DrakeToIgn):
    """draw -> `Pose_V`: a Pose per link, named with the link's Drake name."""

    message_name = "Pose_V"

    def translate(self, channel: str, data: bytes) -> Outputs:
        return [(0, bytes(ign.pose_v(self.decoder.decode(data), self.msgs).SerializeToString()))]


class DrakeToIgnPosesStamped(_DrakeToIgn):
    """draw -> the legacy `PosesStamped` (sim time in `time` too), for older tools."""

    message_name = "PosesStamped"

    def translate(self, channel: str, data: bytes) -> Outputs:
        return [(0, bytes(ign.poses_stamped(self.decoder.decode(data), self.msgs).SerializeToString()))]


class IgnPoseVToDrakeDraw(Translator):
    """ign `Pose_V` -> `lcmt_viewer_draw` (names from `Pose.name`; robot_nums from
    `options.robot_nums`, a name -> number mapping, else 0)."""

    source = "ign"
    destination = "lcm"
    outputs = (Output("", DRAW.type_name),)

    def __init__(self, options: dict[str, Any], loads: LoadCache) -> None:
        super().__init__(options, loads)
        self.msgs = ign.GZ if options.get("package") == "gz" else ign.IGNITION
        self.source_type = self.msgs.full_name("Pose_V")
        self.encoder = DrawEncoder()

    def translate(self, channel: str, data: bytes) -> Outputs:
        message = self.msgs.parse("Pose_V", data)
        poses = ign.poses_from_pose_v(message, self.options.get("robot_nums"))
        return [(0, self.encoder.encode(poses))]


_BYTES_PREFIX = struct.Struct("<4sII")  # encapsulation, layout.dim (empty), layout.data_offset


class LcmBytesToRos(Translator):
    """Any LCM message -> its bytes in a `std_msgs/UInt8MultiArray`: no translation at all,
    the baseline the benchmarks measure the translators against."""

    source = "lcm"
    destination = "ros"
    outputs = (Output("", "std_msgs/msg/UInt8MultiArray"),)

    def translate(self, channel: str, data: bytes) -> Outputs:
        return [(0, _BYTES_PREFIX.pack(b"\x00\x01\x00\x00", 0, 0) + struct.pack("<I", len(data)) + data)]


TRANSLATORS: dict[str, type[Translator]] = {
    "drake_to_marker_array": DrakeToMarkerArray,
    "drake_to_pose_array": DrakeToPoseArray,
    "drake_to_shapes": DrakeToShapes,
    "drake_to_clock": DrakeToClock,
    "drake_link_to_marker_array": DrakeLinkToMarkerArray,
    "ros_pose_array_to_drake_draw": RosPoseArrayToDrakeDraw,
    "lcm_bytes_to_ros": LcmBytesToRos,
    "tree_viewer_server": TreeViewerServer,
    "drake_to_tree_viewer": DrakeToTreeViewer,
    "drake_to_ign_model": DrakeToIgnModel,
    "drake_to_ign_model_v": DrakeToIgnModelV,
    "drake_to_ign_pose_v": DrakeToIgnPoseV,
    "drake_to_ign_poses_stamped": DrakeToIgnPosesStamped,
    "ign_pose_v_to_drake_draw": IgnPoseVToDrakeDraw,
}
