"""The fuzz targets: bytes into one real entry point each, and the errors it documents for bad input.

A target runs one input through the same call the bridge makes on bytes from outside (a
transport's payload, an uploaded form, a config file) and may raise only its documented error
types; anything else, a hang or unbounded memory is a finding (see bench/fuzz.py).

Adding a target is one line: `register(Target("name", function, (DocumentedError,), ("seed kind",)))`.
Seed kinds are what tests/fuzz/seeds.py writes: every LCM type by its full name (from a real Drake
capture, so a new schema Drake publishes gets seeds and a target with no code here), plus
"ign.Pose_V", "ign.Model", "ign.discovery", "gltf", "render_form", "sensor_msgs/PointCloud2", "config",
the rmw_zenoh kinds "rmw_zenoh.data_key", "rmw_zenoh.token" and "rmw_zenoh.attachment", and the
Foxglove front's "foxglove_client_stream", "foxglove_client_messages", "foxglove_handshake",
"foxglove_slow_handshake" and "origin_match".

This module imports `bridge` at its top on purpose: the fuzz runner imports it inside
`atheris.instrument_imports()`, so that every bridge module is instrumented for coverage.
"""

from __future__ import annotations

import functools
import inspect
import json
import re
import struct
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer_bridge.cli import bag_files
from viewer_bridge.config.bridge import load_config
from viewer_bridge.errors import (
    BadRequest,
    ConfigError,
    DamagedChunk,
    DecodeError,
    EncodeError,
    FrameLimitError,
    GltfError,
    HandshakeError,
    JsonValueError,
    RequestRejected,
    SceneError,
    SchemaError,
)
from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.drake.draw import DrawDecoder
from viewer_bridge.formats.drake.image import read_image_array, unpack
from viewer_bridge.formats.drake.load import decode_load
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm, cloud_to_lcm
from viewer_bridge.formats.gltf import read_gltf
from viewer_bridge.formats.ign.model import scene_from_model
from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr
from viewer_bridge.lcmcodec.cdr import CdrTranscoder, compile_transcoders
from viewer_bridge.lcmcodec.cdr_to_lcm import LcmEncoder
from viewer_bridge.lcmcodec.codecs import CODECS, LOAD_ROBOT, STRUCTS, VIEWER2_COMMS
from viewer_bridge.lcmcodec.from_ros import load_ros_definitions, map_ros_types
from viewer_bridge.lcmcodec.library import LcmType, TypeLibrary
from viewer_bridge.lcmcodec.ros_cdr import compile_ros_encoders
from viewer_bridge.lcmcodec.rosmsg import map_to_ros
from viewer_bridge.lcmcodec.schema import check_references, parse_lcm
from viewer_bridge.lcmcodec.serde import StructCodec
from viewer_bridge.model.skipped import collecting
from viewer_bridge.render.renderer import Camera
from viewer_bridge.render.server import parse_form, render_request
from viewer_bridge.translators.drake_ign import IgnPoseVToDrakeDraw
from viewer_bridge.translators.drake_image import DrakeImagesToFoxglove, DrakeImagesToRos, RosImageToDrake
from viewer_bridge.translators.tree_viewer import TreeViewerServer
from viewer_bridge.transports.base import Received
from viewer_bridge.transports.foxglove_clients import ClientPublishing
from viewer_bridge.transports.foxglove_front import (
    HANDSHAKE_SECONDS,
    MAX_HEAD,
    SDK_SUBPROTOCOL,
    Connection,
    RequestHead,
    foxglove_gate,
    http_response,
    naming,
    older_name_asked,
    origin_refusal,
    read_head,
    subprotocols,
)
from viewer_bridge.transports.ign_discovery import ANY_TYPE, Discovery, Record, is_tcp_address
from viewer_bridge.transports.ign_environment import NodeEnvironment
from viewer_bridge.transports.origins import FOXGLOVE_APPS, Origins, origin_matches
from viewer_bridge.transports.websocket_frames import (
    BINARY,
    TEXT,
    ClientMessages,
    Message,
    RelayedStream,
    unmask,
)
from viewer_bridge.transports.zenoh import keys as zenoh_keys


@dataclass(frozen=True)
class Target:
    name: str
    run: Callable[[bytes], object]
    documented: tuple[type[Exception], ...]  # what bad input may raise; anything else is a finding
    seed_kinds: tuple[str, ...]


TARGETS: dict[str, Target] = {}


def register(target: Target) -> None:
    if target.name in TARGETS:
        raise ValueError(f"fuzz target {target.name!r} is registered twice")
    TARGETS[target.name] = target


# --- LCM: every schema's generated codec, and the Drake decoders on top ---------------------------------


# One target for every schema's codec, not one per schema: each target is a process that
# instruments the bridge before its first input, seconds of CPU the suite's short run paid 28 times.
LCM_CODECS: list[StructCodec] = sorted(CODECS.values(), key=lambda codec: codec.type_name)


def lcm_codecs(data: bytes) -> object:
    """The first byte picks a schema's codec (`LCM_CODECS`, modulo their count); the rest is a
    message of that type, fingerprint first."""
    if not data:
        return None
    return LCM_CODECS[data[0] % len(LCM_CODECS)].decode(data[1:])


register(Target("lcm_codecs", lcm_codecs, (DecodeError,), ("lcm_codecs",)))

register(Target("drake_load_scene", decode_load, (DecodeError,), (LOAD_ROBOT.type_name,)))
register(Target("drake_draw_fast", DrawDecoder().decode, (DecodeError,), ("drake.lcmt_viewer_draw",)))


# --- Director's tree viewer: the server's whole request path --------------------------------------------

_MESH_ROOT = tempfile.mkdtemp(prefix="fuzz-meshes-")


def tree_viewer_request(data: bytes) -> object:
    """One envelope from a new client: decode, apply to its tree, reply, and the MarkerArray."""
    replies: list[bytes] = []
    server = TreeViewerServer(
        {"mesh_roots": [_MESH_ROOT]}, reply=lambda channel, payload: replies.append(payload)
    )
    try:
        return server.translate(Received("DIRECTOR_TREE_VIEWER_REQUEST_<fuzz>", data, 0))
    finally:
        if len(replies) != 1:  # the protocol's promise: every request gets exactly one reply
            raise AssertionError(f"{len(replies)} replies to one request")


register(
    Target(
        "tree_viewer_request", tree_viewer_request, (RequestRejected, SceneError), (VIEWER2_COMMS.type_name,)
    )
)


# --- ign / gz protobuf ----------------------------------------------------------------------------------

_POSE_V_TO_DRAW = IgnPoseVToDrakeDraw()


def ign_pose_v(data: bytes) -> object:
    """What the `from_ign` route does with a Pose_V: parse, poses, lcmt_viewer_draw bytes."""
    return _POSE_V_TO_DRAW.translate(Received("/drake_in/pose_v", data, 0))


def ign_model(data: bytes) -> object:
    return scene_from_model(MESSAGES.parse("Model", data))


register(Target("ign_pose_v", ign_pose_v, (DecodeError, SceneError, EncodeError), ("ign.Pose_V",)))
register(Target("ign_model", ign_model, (DecodeError, SceneError), ("ign.Model",)))


# --- ign/gz-transport discovery datagrams ---------------------------------------------------------------

# What the fuzzed node wants and offers, so that seeds (tests/fuzz/seeds.py) reach every answer.
DISCOVERY_SUBSCRIBED = "@/fuzz@/drake_in/pose_v"  # gz.msgs.Pose_V
DISCOVERY_ANY = "@/fuzz@/anything"  # any type
DISCOVERY_ADVERTISED = "@/fuzz@/drake/pose_v"
DISCOVERY_RELAY = "10.0.0.2"


def ign_discovery(data: bytes) -> object:
    """One datagram as an ign node reads it, from the group, with a relay set: every message type of
    both wire versions is answered, forwarded or counted. Nothing is sent or dialled: what the node
    would send must be a datagram it can read back, and an address it would connect to must have
    passed the tcp://host:port check."""
    sent: list[tuple[bytes, tuple[str, int]]] = []
    dialled: list[str] = []

    def send(datagram: bytes, destination: tuple[str, int]) -> None:
        if struct.unpack_from("<H", datagram)[0] != len(datagram) - 2:
            raise AssertionError(f"a datagram to {destination} whose length prefix disagrees")
        Record.FromString(datagram[2:])
        sent.append((datagram, destination))

    def connect(address: str) -> None:
        if not is_tcp_address(address):
            raise AssertionError(f"asked to connect to {address!r}")
        dialled.append(address)

    node = Discovery(NodeEnvironment(relays=(DISCOVERY_RELAY,)), "tcp://127.0.0.1:1", send, connect,
                     lambda kind, text: None)  # fmt: skip
    node.subscribe(DISCOVERY_SUBSCRIBED, "gz.msgs.Pose_V")
    node.subscribe(DISCOVERY_ANY, ANY_TYPE)
    node.advertise(DISCOVERY_ADVERTISED, "gz.msgs.Pose_V")
    node.on_datagram(data, "127.0.0.1", 0.0)
    node.beat(10.0)  # and a heartbeat later, when every peer it heard is silent
    return sent, dialled


register(Target("ign_discovery", ign_discovery, (), ("ign.discovery",)))


# --- glTF and the render server's form ------------------------------------------------------------------


def gltf(data: bytes) -> object:
    return read_gltf(data).to_scene()


def _blank_render(scene: object, camera: Camera, kind: str) -> np.ndarray:
    """Stands in for the GL thread, so the form path runs before and after it without a GPU.

    One pixel, whatever the camera says: a form may ask for 8192 x 8192 (the documented limit),
    and a gigabyte image per input would measure the stub, not the parser.
    """
    return np.zeros((1, 1, 4), np.float32)


def render_form(data: bytes) -> object:
    """An upload as the server reads it: the Content-Type header line, then the body."""
    content_type, _, body = data.partition(b"\n")
    fields = parse_form(content_type.decode("latin-1"), body)  # http.server's header decoding
    return render_request(fields, _blank_render)


register(Target("gltf", gltf, (GltfError,), ("gltf",)))
register(Target("render_form", render_form, (BadRequest,), ("render_form",)))


# --- what meldis shows: contact results and point clouds, both ways ----------------------------------


def ros_point_cloud(data: bytes) -> object:
    """What the `point_cloud_from_ros` route does with a PointCloud2: read it, write lcmt_point_cloud."""
    return cloud_to_lcm(cloud_from_cdr(data))


register(
    Target(
        "drake_contact_results",
        decode_contact_results,
        (DecodeError,),
        ("drake.lcmt_contact_results_for_viz",),
    )
)
register(Target("drake_point_cloud", cloud_from_lcm, (DecodeError,), ("drake.lcmt_point_cloud",)))
register(Target("ros_point_cloud2", ros_point_cloud, (DecodeError,), ("sensor_msgs/PointCloud2",)))


# --- rmw_zenoh's names and stamps: what the Zenoh transport parses from other sessions --------------------
# Key expressions reach Python as text; the bytes are read as latin-1 so that every input is one.

register(Target("zenoh_data_key", lambda data: zenoh_keys.parse_data_key(data.decode("latin-1")), (DecodeError,),
                ("rmw_zenoh.data_key",)))  # fmt: skip
register(Target("zenoh_token", lambda data: zenoh_keys.parse_token(data.decode("latin-1")), (DecodeError,),
                ("rmw_zenoh.token",)))  # fmt: skip
register(Target("zenoh_attachment", zenoh_keys.parse_attachment, (DecodeError,), ("rmw_zenoh.attachment",)))


# --- camera images, both ways ---------------------------------------------------------------------------


def drake_images(data: bytes) -> object:
    """Every image of an `lcmt_image_array` to pixels, as the camera routes unpack them."""
    return [unpack(packed) for packed in read_image_array(data).images]


_EVERY_OUTPUT = {
    "compressed": "png",
    "depth": "32FC1",
    "drop_alpha": True,
    "camera_info": {"width": 4, "height": 3, "fov_y": 45},
}
_IMAGES_TO_ROS = DrakeImagesToRos(_EVERY_OUTPUT)
_IMAGES_TO_FOXGLOVE = DrakeImagesToFoxglove(_EVERY_OUTPUT)
_ROS_TO_DRAKE = RosImageToDrake()


def drake_images_to_ros(data: bytes) -> object:
    """The `camera_images` route with every output on: a bad image is collected, the rest written."""
    received = Received("DRAKE_RGBD_CAMERA_IMAGES_fuzz", data, 0)
    _IMAGES_TO_ROS.observe(received)
    with collecting():
        return _IMAGES_TO_ROS.translate(received)


def drake_images_to_foxglove(data: bytes) -> object:
    """The `foxglove_camera_images` route with every output on."""
    received = Received("DRAKE_RGBD_CAMERA_IMAGES_fuzz", data, 0)
    _IMAGES_TO_FOXGLOVE.observe(received)
    with collecting():
        return _IMAGES_TO_FOXGLOVE.translate(received)


def ros_image_to_drake(data: bytes) -> object:
    """What the `camera_image_from_ros` route does with a sensor_msgs/Image: read, lcmt_image_array."""
    return _ROS_TO_DRAKE.translate(Received("/drake_in/camera/image", data, 0))


register(Target("drake_images", drake_images, (DecodeError,), ("drake.lcmt_image_array",)))
register(Target("drake_images_to_ros", drake_images_to_ros, (DecodeError,), ("drake.lcmt_image_array",)))
register(
    Target("drake_images_to_foxglove", drake_images_to_foxglove, (DecodeError,), ("drake.lcmt_image_array",))
)
register(Target("ros_image_to_drake", ros_image_to_drake, (DecodeError, EncodeError), ("sensor_msgs/Image",)))


# --- any LCM type: the .lcm parser and mapping, and the generic LCM -> CDR transcoder --------------------

_CORPUS = Path(__file__).resolve().parent.parent / "lcmtypes_corpus"
GENERIC_TYPES = (  # several shapes: multi-dimensional, nested across packages, strings, an empty struct
    "lab.robot.arm_state_t",
    "lab.robot.pulse_t",
    "plain_status_t",
    "drake.lcmt_iiwa_status",
    "drake.lcmt_robot_plan",
)
_GENERIC = TypeLibrary.load([str(_CORPUS)])


def _instrument_generated_code() -> None:
    """Under the fuzzer, instrument the transcoders and decoders generated for GENERIC_TYPES too:
    they are compiled from source text at run time, which `atheris.instrument_imports` never sees."""
    atheris = sys.modules.get("atheris")
    if atheris is None:
        return
    functions = [_GENERIC.get(name).transcoder._body for name in GENERIC_TYPES]
    functions += [_GENERIC.codecs(name)[name]._decode_body for name in GENERIC_TYPES]
    for namespace in {id(function.__globals__): function.__globals__ for function in functions}.values():
        for value in list(namespace.values()):
            if inspect.isfunction(value) and value.__code__.co_filename.startswith("<lcm"):
                atheris.instrument_func(value)


_instrument_generated_code()


def lcm_schema(data: bytes) -> object:
    """A `.lcm` file as `--lcm-types FILE` reads it: parse, resolve, and map every type to ROS 2."""
    structs = {struct.full_name: struct for struct in parse_lcm(data.decode("latin-1"), "fuzz.lcm")}
    pending = list(structs.values())
    while pending:  # the project's types may be named (the seeds are its own files, one type each)
        for member in pending.pop().members:
            if not member.is_primitive and member.type_name not in structs and member.type_name in STRUCTS:
                structs[member.type_name] = STRUCTS[member.type_name]
                pending.append(STRUCTS[member.type_name])
    check_references(structs)
    mapping = map_to_ros(structs)
    return [mapping.ros2msg(name) for name in mapping.messages]


_GENERATED_ONLY: dict[str, CdrTranscoder] = {}  # transcoders that keep no layout, by type


def _generated_only(known: LcmType) -> CdrTranscoder:
    """`known`'s transcoder that runs the generated code on every message."""
    if known.full_name not in _GENERATED_ONLY:
        closure = _GENERIC.closure(known.full_name)
        fingerprints = {name: _GENERIC.get(name).packed_fingerprint for name in closure}
        compiled = compile_transcoders(closure, fingerprints, [known.full_name], keep_layouts=False)
        _GENERATED_ONLY[known.full_name] = compiled[known.full_name]
    return _GENERATED_ONLY[known.full_name]


def lcm_generic(data: bytes) -> object:
    """The first byte picks a type (or none: the bytes are a whole message of any known type); the
    rest is the message after its fingerprint. The CDR transcoder and the JSON decoder must agree
    about whether it is valid, and the transcoder's kept layouts (messages of a size seen before)
    must give the generated code's bytes."""
    choice = data[0] if data else 0
    if choice < len(GENERIC_TYPES):
        known = _GENERIC.get(GENERIC_TYPES[choice])
        message = known.packed_fingerprint + data[1:]
    else:
        message = data[1:]
        found = _GENERIC.for_data(message)
        if found is None or found.ros_type is None:
            return None
        known = found
    try:
        cdr: bytes | None = known.to_cdr(message)
    except DecodeError:
        cdr = None
    try:
        known.to_json(message)
    except DecodeError:
        if cdr is not None:
            raise AssertionError("the transcoder took a message the JSON decoder refuses") from None
        raise
    if cdr is None:
        raise AssertionError("the JSON decoder took a message the transcoder refuses")
    if cdr != _generated_only(known).transcode(message):
        raise AssertionError("a kept layout and the generated code give different CDR")
    return cdr


register(Target("lcm_schema", lcm_schema, (SchemaError,), ("lcm_schema",)))
register(Target("lcm_generic", lcm_generic, (DecodeError,), ("lcm_generic",)))


# --- any LCM type, back: CDR -> LCM and JSON -> LCM -------------------------------------------------------

BACK_TYPES = (*GENERIC_TYPES, "drake.lcmt_iiwa_command")  # the last: numbers only, its layouts kept


def _instrument_back_code() -> None:
    """Under the fuzzer, instrument the CDR -> LCM code generated for BACK_TYPES too."""
    atheris = sys.modules.get("atheris")
    if atheris is None:
        return
    for name in BACK_TYPES:
        namespace = _GENERIC.get(name).encoder._body.__globals__
        for value in list(namespace.values()):
            if inspect.isfunction(value) and value.__code__.co_filename.startswith("<cdr"):
                atheris.instrument_func(value)


_instrument_back_code()


_ORACLE_DECODE_LIMIT = 1 << 16  # bytes: decoding a million-element array to Python objects is the oracle's
# cost, not the code's (a second, under instrumentation), and libFuzzer reports it as a slow unit


def _lcm_is_valid(known: LcmType, lcm: bytes) -> None:
    """What the way back wrote must be the type's LCM: it goes to CDR and back unchanged, and
    (when not huge) decodes."""
    if len(lcm) <= _ORACLE_DECODE_LIMIT:
        known.to_json(lcm)
    if known.from_cdr(known.to_cdr(lcm)) != lcm:
        raise AssertionError("LCM -> CDR -> LCM changed the message")


def lcm_back_cdr(data: bytes) -> object:
    """The first byte picks a type of BACK_TYPES, the rest is CDR (header included) as a ROS 2
    publisher or a Foxglove client sends it. What is taken must be valid LCM, and the same as the
    generated code alone makes of it (the kept layouts of a numbers-only type are a shortcut)."""
    known = _GENERIC.get(BACK_TYPES[data[0] % len(BACK_TYPES)] if data else BACK_TYPES[0])
    cdr = data[1:]
    lcm = known.from_cdr(cdr)
    if known.encoder.generated(cdr) != lcm:
        raise AssertionError("the kept layout and the generated code disagree")
    _lcm_is_valid(known, lcm)
    return lcm


_JSON_OPS = 12
_HUGE_LIST = 1 << 20


def json_value(data: bytes, names: list[str]) -> object:
    """A JSON value built from bytes by a small stack machine (no recursion, so nesting may be as
    deep as the input is long): numbers of every size (NaN, infinities and 2000-bit integers
    included), strings, booleans, null, arrays, objects keyed by the type's field names or not,
    and arrays of up to a million elements."""
    root: list[object] = []
    stack: list[list[object] | dict[str, object]] = [root]
    at = 0

    def take(count: int) -> bytes:
        nonlocal at
        chunk = data[at : at + count]
        at += count
        return chunk

    while at < len(data):
        op = data[at] % _JSON_OPS
        at += 1
        value: object
        if op == 0:
            value = int.from_bytes(take(1), "little", signed=True)
        elif op == 1:
            size = take(1)
            value = int.from_bytes(take(size[0] if size else 0), "little", signed=True)
        elif op == 2:
            raw = take(8).ljust(8, b"\0")
            value = struct.unpack("<d", raw)[0]
        elif op == 3:
            size = take(1)
            value = take(size[0] if size else 0).decode("utf-8", "surrogateescape" if at % 2 else "replace")
        elif op == 4:
            value = bool(at % 2)
        elif op == 5:
            value = None
        elif op == 6:
            stack.append([])
            continue
        elif op == 7:
            stack.append({})
            continue
        elif op == 8 and len(stack) > 1:
            value = stack.pop()
        elif op == 9:
            size = int.from_bytes(take(3), "little") % _HUGE_LIST
            value = [0.5 if at % 2 else 1] * size
        elif op == 10:
            value = list(take(take(1)[0] if at < len(data) else 0))  # bytes as a list of 0..255
        else:
            continue
        top = stack[-1]
        if isinstance(top, dict):
            pick = take(1)
            top[names[pick[0] % len(names)] if pick and pick[0] < 240 else f"x{len(top)}"] = value
        else:
            top.append(value)
    while len(stack) > 1:  # close what is open
        value = stack.pop()
        top = stack[-1]
        if isinstance(top, dict):
            top[names[len(top) % len(names)]] = value
        else:
            top.append(value)
    return root[0] if root else {}


def _ros_names(known: LcmType) -> list[str]:
    """Every ROS 2 field name of `known` and of the types it nests."""
    from viewer_bridge.lcmcodec.rosnames import field_name

    return sorted({field_name(member.name) for definition in _GENERIC.closure(known.full_name).values()
                   for member in definition.members})  # fmt: skip


_BACK_NAMES = {name: _ros_names(_GENERIC.get(name)) or ["x"] for name in BACK_TYPES}


def lcm_back_json(data: bytes) -> object:
    """The first byte picks a type of BACK_TYPES and how the rest becomes a JSON value: parsed
    as JSON text (when it is), or built by `json_value`. What is taken must be valid LCM."""
    choice = data[0] if data else 0
    name = BACK_TYPES[choice % len(BACK_TYPES)]
    known = _GENERIC.get(name)
    value: object
    if choice >= 128:
        try:
            value = json.loads(data[1:])
        # not JSON, or too deep for Python's parser: the transport's concern
        except (ValueError, RecursionError):
            return None
    else:
        value = json_value(data[1:], _BACK_NAMES[name])
    lcm = known.from_json(value)
    _lcm_is_valid(known, lcm)
    return lcm


register(Target("lcm_back_cdr", lcm_back_cdr, (DecodeError,), ("lcm_back_cdr",)))
register(Target("lcm_back_json", lcm_back_json, (JsonValueError,), ("lcm_back_json",)))


# --- any ROS 2 type onto LCM: ROS 2 CDR -> LCM (docs/PROTOCOLS.md section 14) ----------------------------

# Sequences of numbers, strings and structs, bounded ones, uint64, bools, wstrings, byte arrays.
ROS_TYPES = ("sensor_msgs/msg/JointState", "my_robot/msg/Gripper", "my_robot/msg/Note", "nav_msgs/msg/Odometry",
             "sensor_msgs/msg/Image")  # fmt: skip
_ROS_MSGS = Path(__file__).resolve().parent.parent / "lcmcodec" / "ros_msgs"


@functools.cache
def _ros_encoders() -> tuple[dict[str, LcmEncoder], dict[str, LcmEncoder], TypeLibrary]:
    """The encoders of ROS_TYPES with their kept layouts and without, and the generated `.lcm`
    types loaded as any LCM type is (the oracle: what is written must decode as its type). Made
    at the first input, not at import: every other target's process imports this module too.
    Under the fuzzer, the code generated for them is instrumented as well."""
    definitions, _ = load_ros_definitions([str(_ROS_MSGS)])
    mapping = map_ros_types(definitions, ROS_TYPES)
    folder = Path(tempfile.mkdtemp(prefix="fuzz-ros-lcm-"))
    mapping.write(folder)
    kept, generated = (
        compile_ros_encoders(mapping, ROS_TYPES),
        compile_ros_encoders(mapping, ROS_TYPES, keep_layouts=False),
    )
    atheris = sys.modules.get("atheris")
    for encoder in [*kept.values(), *generated.values()] if atheris is not None else ():
        for value in list(encoder._body.__globals__.values()):
            if inspect.isfunction(value) and value.__code__.co_filename.startswith("<ros cdr"):
                atheris.instrument_func(value)
    return kept, generated, TypeLibrary.load([str(folder)], drake=False)


def ros_cdr_to_lcm(data: bytes) -> object:
    """The first byte picks a type of ROS_TYPES, the rest is its CDR (header included) as a bag or
    a ROS 2 publisher holds it. Only `DecodeError` may come out (no IndexError, struct.error, nor an
    allocation for a count of 2^31 elements: the RSS limit catches one); what is taken is the same
    with the kept layouts as with the generated code alone, and is LCM of the type."""
    kept, generated, library = _ros_encoders()
    name = ROS_TYPES[data[0] % len(ROS_TYPES)] if data else ROS_TYPES[0]
    cdr = data[1:]
    lcm = kept[name].encode(cdr)
    if generated[name].encode(cdr) != lcm:
        raise AssertionError("the kept layout and the generated code disagree")
    if len(lcm) <= _ORACLE_DECODE_LIMIT:
        library.type_of(lcm).to_json(lcm)
    return lcm


register(Target("ros_cdr_to_lcm", ros_cdr_to_lcm, (DecodeError,), ("ros_cdr_to_lcm",)))


# --- the Foxglove front: what a client sends, read along; a request's head at the door -------------------

FOXGLOVE_MAX_MESSAGE = 4096  # small, so that messages past the limit are common
FOXGLOVE_MAX_CHANNELS = 4
FOXGLOVE_ROUTE = "/lcm_in/(.*)"
FOXGLOVE_ORIGINS = Origins(["https://*.lab.example", "http://[::1]:*"], trusted=FOXGLOVE_APPS)


class RecordingConnection(Connection):
    """A client as ClientPublishing sees it, with no socket: what the bridge says to it is kept."""

    def __init__(self) -> None:  # no Connection.__init__: nothing here is relayed
        self.address = "fuzz:0"
        self.said: list[str] = []

    def send_text(self, text: str) -> bool:
        self.said.append(text)
        return True


def _read_along(stream: bytes, chunk: int) -> tuple[list[Message], list[str], list[Received]]:
    """`stream` as a client sends it, in reads of `chunk` bytes, through the front's reader and
    ClientPublishing; checks what it may keep and say, and that closing forgets the client."""
    delivered: list[Received] = []
    publishing = ClientPublishing(FOXGLOVE_MAX_CHANNELS)
    publishing.subscribe(FOXGLOVE_ROUTE, delivered.append)
    connection = RecordingConnection()
    reader = ClientMessages(FOXGLOVE_MAX_MESSAGE, "foxglove.max_client_message_bytes")
    messages: list[Message] = []
    for start in range(0, len(stream), chunk):
        for message in reader.feed(memoryview(stream)[start : start + chunk]):
            messages.append(message)
            publishing.message(connection, message)
            if publishing.remembered()[0] > FOXGLOVE_MAX_CHANNELS:  # one client here
                raise AssertionError("a client kept more channels than max_channels")
    for message in messages:
        if message.opcode not in (TEXT, BINARY) or len(message.payload) > FOXGLOVE_MAX_MESSAGE:
            raise AssertionError(f"read along: opcode {message.opcode}, {len(message.payload)} bytes")
    for text in connection.said:
        said = json.loads(text)
        if (
            said["op"] != "status"
            or said["level"] != 2
            or len(said["message"]) > 1100
            or len(said["id"]) > 1100
        ):
            raise AssertionError(f"said {text[:200]!r}")
    for received in delivered:
        if re.fullmatch(FOXGLOVE_ROUTE, received.channel) is None or received.origin is not connection:
            raise AssertionError(f"delivered {received.channel!r} from {received.origin!r}")
    publishing.closed(connection)
    if publishing.remembered() != (0, 0):
        raise AssertionError("a closed connection is still remembered")
    return messages, connection.said, delivered


def foxglove_client_stream(data: bytes) -> object:
    """The first byte picks the size of each read (1 to 256 bytes); the rest is the stream."""
    return _read_along(data[1:], (data[0] if data else 0) + 1)


def client_frames(data: bytes) -> bytes:
    """Records `flags | u16 LE length | payload` as the masked frames a client sends: flags' low
    nibble is the opcode, 0x80 FIN, 0x40 RSV1; 0x20 picks the 16-bit length field even for a
    short payload and 0x10 the 64-bit one; the mask is the record's first four payload bytes."""
    frames = bytearray()
    at = 0
    while at + 3 <= len(data):
        flags, length = data[at], struct.unpack_from("<H", data, at + 1)[0]
        payload = data[at + 3 : at + 3 + length]
        at += 3 + length
        mask = (payload[:4] + b"\x00" * 4)[:4]
        if flags & 0x10:
            size = bytes([0x80 | 127]) + len(payload).to_bytes(8, "big")
        elif flags & 0x20 or len(payload) > 125:
            size = bytes([0x80 | 126]) + len(payload).to_bytes(2, "big")
        else:
            size = bytes([0x80 | len(payload)])
        frames += bytes([flags & 0xCF]) + size + mask + unmask(payload, mask)
    return bytes(frames)


def foxglove_client_messages(data: bytes) -> object:
    """Whole frames of the fuzzer's payloads (`client_frames`), so the JSON and the message data
    are what mutates; read in reads of a size the first byte picks."""
    return _read_along(client_frames(data[1:]), (data[0] if data else 0) * 8 + 1)


class _Chunks:
    """A socket's `recv` over fixed bytes, a few at a time, then the end."""

    def __init__(self, data: bytes, size: int) -> None:
        self._data, self._size, self._at = data, size, 0

    def recv(self, size: int, /) -> bytes:
        taken = self._data[self._at : self._at + min(size, self._size)]
        self._at += len(taken)
        return taken


def foxglove_handshake(data: bytes) -> object:
    """A request's head as the front reads it (the first byte picks the read size): its
    subprotocols renamed for the SDK, and its origin checked; a refusal is a well-formed answer."""
    request, _ = read_head(_Chunks(data[1:], (data[0] if data else 0) + 1))
    offered = subprotocols(request)
    if offered and subprotocols(naming(request, SDK_SUBPROTOCOL)) != [SDK_SUBPROTOCOL]:
        raise AssertionError("renamed, the request names other subprotocols")
    older_name_asked(request)
    refusal = origin_refusal(request, foxglove_gate(FOXGLOVE_ORIGINS))
    if refusal is None:
        return None
    answer = http_response(refusal)
    head, _, body = answer.partition(b"\r\n\r\n")
    lines = head.split(b"\r\n")
    if lines[0] != b"HTTP/1.1 403 Forbidden" or f"Content-Length: {len(body)}".encode() not in lines:
        raise AssertionError(f"answered {answer[:300]!r}")
    if b"\n" in body[:-1] or b"\r" in body or len(lines) != 4:
        raise AssertionError(f"an origin forged a line: {answer[:300]!r}")
    return answer


def foxglove_slow_handshake(data: bytes) -> object:
    """A request head arriving slowly and in fragments, as the front's accepting thread reads it
    (`RequestHead`, on a clock of the fuzzer's): records `u8 delay | u8 length | bytes`, each a
    read that comes `delay` x 0.1 s after the previous one (0 to 25.5 s); a record cut short is
    the peer closing. Checked against a plain reading of what came: the head is found exactly
    when the bytes so far hold a blank line within MAX_HEAD and the one deadline has not passed;
    nothing is found past the deadline, however short each wait was."""
    start = clock = 1000.0
    head = RequestHead(start + HANDSHAKE_SECONDS)
    sent = bytearray()
    at = 0
    while True:
        if at + 2 > len(data):
            chunk = b""  # the peer closes
        else:
            clock += data[at] * 0.1
            chunk = data[at + 2 : at + 2 + data[at + 1]]
            at += 2 + data[at + 1]
            if not chunk:
                continue  # a read of nothing is no read (a socket returns b"" only at its end)
        sent += chunk
        end = sent.find(b"\r\n\r\n")
        in_time = clock <= start + HANDSHAKE_SECONDS
        whole = end >= 0 and end + 4 <= MAX_HEAD
        try:
            found = head.feed(chunk, clock)
        except HandshakeError:
            if chunk and in_time and (whole or len(sent) <= MAX_HEAD):
                raise AssertionError(f"refused in time, {len(sent)} bytes, head end at {end}") from None
            raise
        if found is None:
            if whole or not in_time:
                raise AssertionError(
                    f"nothing found nor refused at {clock - start:.1f} s ({len(sent)} bytes)"
                )
            continue
        request, early = found
        if not in_time or not whole or request != bytes(sent[: end + 4]) or request + early != sent:
            raise AssertionError(
                f"found at {clock - start:.1f} s a head of {len(request)} bytes of {len(sent)}"
            )
        return request


def _star_match(pattern: str, text: str) -> bool:
    """The allowed-origin rule, written again as a plain dynamic programme (the test's own): `*`
    any run of characters but `/`, every other character itself, ASCII letters in either case."""
    pattern, text = pattern.translate(_ASCII_LOWER), text.translate(_ASCII_LOWER)
    matched = [True] + [False] * len(text)  # which prefixes of text the pattern's prefix matches
    for character in pattern:
        if character == "*":
            for index in range(1, len(text) + 1):
                matched[index] = matched[index] or (matched[index - 1] and text[index - 1] != "/")
        else:
            matched = [False] + [matched[index] and text[index] == character for index in range(len(text))]
    return matched[-1]


_ASCII_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")


_ORACLE_STEPS = 200_000  # entry x origin characters the slow oracle takes on (the matcher takes on any)


def origin_match(data: bytes) -> object:
    """An allowed entry and an origin, split at the first NUL: the matcher and `_star_match` agree
    (the oracle, quadratic, only on inputs small enough for it)."""
    entry, _, origin = data.decode("latin-1").partition("\0")
    found = origin_matches(entry, origin)
    if len(entry) * len(origin) <= _ORACLE_STEPS and found != _star_match(entry, origin):
        raise AssertionError(f"{entry!r} against {origin!r}: the matcher says {found}")
    return found


register(
    Target("foxglove_client_stream", foxglove_client_stream, (FrameLimitError,), ("foxglove_client_stream",))
)


SDK_TEXT_HELD = 4096  # the front holds back up to MAX_SDK_TEXT; a smaller limit reaches both sides of it


def foxglove_sdk_stream(data: bytes) -> object:
    """What the SDK sends a client, through the front's relay (`RelayedStream`): the first byte
    picks the size of each read (1 + 8 x the byte: 1 to 2041 bytes, so that a long stream is not
    always read byte by byte); every other read asks for a cut at the next message end. Every
    byte must pass on in order, nothing held back but one frame under way, and a text frame held
    back whole must end with the payload it is read as."""
    chunk, stream = 1 + 8 * (data[0] if data else 0), data[1:]
    relayed = RelayedStream(SDK_TEXT_HELD)
    out = bytearray()
    for index, start in enumerate(range(0, len(stream), chunk)):
        for piece in relayed.feed(memoryview(stream)[start : start + chunk], cut_first_end=index % 2 == 1):
            if piece.text is not None and not bytes(piece.data).endswith(piece.text):
                raise AssertionError("a held text frame's payload is not its last bytes")
            out += piece.data
    if not stream.startswith(out):
        raise AssertionError("relayed bytes differ from the stream's, or came out of order")
    if len(stream) - len(out) > SDK_TEXT_HELD + 14:  # a held frame (14: the longest header)
        raise AssertionError(f"{len(stream) - len(out)} bytes held back at the end")
    return out


register(Target("foxglove_sdk_stream", foxglove_sdk_stream, (), ("foxglove_sdk_stream",)))
register(
    Target(
        "foxglove_client_messages",
        foxglove_client_messages,
        (FrameLimitError,),
        ("foxglove_client_messages",),
    )
)
register(Target("foxglove_handshake", foxglove_handshake, (HandshakeError,), ("foxglove_handshake",)))
register(
    Target(
        "foxglove_slow_handshake", foxglove_slow_handshake, (HandshakeError,), ("foxglove_slow_handshake",)
    )
)
register(Target("origin_match", origin_match, (), ("origin_match",)))


# --- a ROS 2 bag's MCAP file, as `convert` reads it ------------------------------------------------------

_BAG = Path(tempfile.mkdtemp(prefix="fuzz-bag-")) / "bag.mcap"


def mcap_reader(data: bytes) -> object:
    """MCAP's magic bytes, then `data`, read as `convert` reads a bag (bag_files): once for its
    topics, once more for every topic's messages. Whatever it holds, a chunk inflates at most one
    byte past the size it declares (the fuzzer's 2 GB memory limit would catch more); a damaged
    chunk is skipped (`DamagedChunk`, said), damage outside one ends the reading (`CutShort`, or
    the `ValueError` or `struct.error` of a record too short for its fields: the reader says it)."""
    _BAG.write_bytes(bag_files._MAGIC + data)
    found: list[bag_files.Connection] = []
    known: dict[tuple[str, str, str], bag_files.Connection] = {}
    damaged: list[str] = []
    for _ in bag_files._mcap(_BAG, known, found, None, damaged):
        raise AssertionError("a message read while only the topics were asked for")
    messages = [(connection.id, stamp, bytes(message)) for connection, stamp, message in
                bag_files._mcap(_BAG, known, found, {c.id for c in found}, damaged)]  # fmt: skip
    return messages, damaged


register(Target("mcap_reader", mcap_reader, (bag_files.CutShort, DamagedChunk, ValueError, struct.error),
                ("mcap_reader",)))  # fmt: skip


# --- the config loader ----------------------------------------------------------------------------------

_CONFIG_FILE = Path(tempfile.mkdtemp(prefix="fuzz-config-")) / "config.yaml"


def config(data: bytes) -> object:
    """A config file as `viewer-bridge --config FILE` reads it."""
    _CONFIG_FILE.write_bytes(data)
    return load_config(_CONFIG_FILE)


register(Target("config", config, (ConfigError,), ("config",)))

__all__ = ["TARGETS", "Target", "register"]
