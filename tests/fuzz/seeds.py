"""Seed inputs for the fuzz targets, from a real Drake run: `write_seeds(folder)` -> folder/<kind>/<hash>.

pydrake's DrakeVisualizer publishes the scene of viewer_bridge/examples/shapes.py (every shape, both roles)
on an in-process LCM; every message it sends is a seed for its type's codec (found by
fingerprint), and each nested struct one for its own type. The other formats' seeds are the
bridge's own encodings of that captured scene: tree viewer envelopes, ign Pose_V and Model, glTF
and a render form with RenderEngineGltfClient's fields; contact results and point clouds (LCM
and PointCloud2) and camera images (lcmt_image_array in every compression, sensor_msgs/Image)
are the bridge's own encodings of small examples; ign discovery datagrams are built here, one per
message type and wire version. The config seeds are the built-in configs.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from tests.formats.ign.oracle import pose_v
from tests.fuzz.targets import DISCOVERY_ADVERTISED, DISCOVERY_ANY, DISCOVERY_SUBSCRIBED, LCM_CODECS
from viewer_bridge.config.bridge import BUILTIN_CONFIGS
from viewer_bridge.examples.shapes import build_simulator
from viewer_bridge.formats.drake.draw import poses_from_draw
from viewer_bridge.formats.drake.load import decode_load
from viewer_bridge.formats.gltf import write_gltf
from viewer_bridge.formats.ign.model import model
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.formats.tree_viewer.requests import draw_request, load_requests
from viewer_bridge.lcmcodec.codecs import DRAW, LOAD_ROBOT, SCHEMA_DIR, VIEWER2_COMMS, codec_for
from viewer_bridge.lcmcodec.serde import LcmMessage, StructCodec
from viewer_bridge.model.scene import Scene
from viewer_bridge.transports.ign_discovery import STATISTICS_VERSION, WIRE_VERSION, Record, datagram

Seeds = dict[str, list[bytes]]


def write_seeds(folder: Path) -> dict[str, int]:
    """Every seed kind's inputs as files under `folder/<kind>/`; returns the count per kind."""
    with tempfile.TemporaryDirectory() as mesh_dir:  # the scene's mesh files, read by the encoders
        seeds = drake_lcm_seeds(Path(mesh_dir))
        for kind, inputs in bridge_encoded_seeds(seeds).items():
            seeds[kind] += inputs
        seeds["render_form"] = [render_form(decode_load(seeds[LOAD_ROBOT.type_name][0]))]
    seeds["ign.discovery"] = discovery_seeds()
    for kind, inputs in {**meldis_seeds(), **image_seeds()}.items():
        seeds[kind] += inputs
        for data in inputs:
            codec = codec_for(data)
            for type_name, encoded in _nested_encoded(codec.decode(data)) if codec is not None else ():
                seeds[type_name].append(encoded)
    seeds["config"] = [text.encode() for text in BUILTIN_CONFIGS.values()]
    seeds.update(zenoh_seeds())
    seeds.update(foxglove_seeds())
    seeds.update(lcm_type_seeds())
    seeds["ros_cdr_to_lcm"] = ros_cdr_seeds()
    seeds["mcap_reader"] = mcap_seeds()
    seeds["lcm_codecs"] = [bytes([index]) + data for index, codec in enumerate(LCM_CODECS)
                           for data in seeds.get(codec.type_name, [])]  # fmt: skip
    for kind, inputs in seeds.items():
        (folder / kind).mkdir(parents=True, exist_ok=True)
        for data in inputs:
            (folder / kind / hashlib.sha1(data).hexdigest()).write_bytes(data)
    return {kind: len(inputs) for kind, inputs in seeds.items()}


def drake_lcm_seeds(mesh_dir: Path, draws_per_channel: int = 3) -> Seeds:
    """What DrakeVisualizer published, by LCM type, and the structs nested in it by theirs."""
    from pydrake.lcm import DrakeLcm

    lcm = DrakeLcm("memq://")
    captured: list[bytes] = []
    lcm.SubscribeAllChannels(lambda channel, data: captured.append(bytes(data)))
    build_simulator(lcm, mesh_dir).AdvanceTo(0.01)
    while lcm.HandleSubscriptions(0):
        pass
    seeds: Seeds = defaultdict(list)
    for data in captured:
        codec = codec_for(data)
        if codec is None:
            continue
        if len(seeds[codec.type_name]) < draws_per_channel * 4:  # the draws repeat; a few suffice
            seeds[codec.type_name].append(data)
        for type_name, encoded in _nested_encoded(codec.decode(data)):
            kind = seeds[type_name]
            if encoded not in kind and len(kind) < 40:
                kind.append(encoded)
    return seeds


def _nested_encoded(message: LcmMessage) -> Iterator[tuple[str, bytes]]:
    """Each struct nested in `message`, as its type's name (its codec's, found by the bytes'
    fingerprint) and its LCM bytes."""
    for nested in _nested_structs(message):
        encoded = nested.encode()
        codec = codec_for(encoded)
        assert codec is not None, f"a nested struct of no known type: {nested!r}"
        yield codec.type_name, encoded


def _nested_structs(message: LcmMessage) -> Iterator[LcmMessage]:
    for name in message.field_names():
        values = getattr(message, name)
        for value in values if isinstance(values, list) else [values]:
            if isinstance(value, LcmMessage):
                yield value
                yield from _nested_structs(value)


def bridge_encoded_seeds(lcm_seeds: Seeds) -> Seeds:
    """The captured scene as the bridge writes it for the other formats the fuzz targets read."""
    load = next(data for data in lcm_seeds[LOAD_ROBOT.type_name])
    scene = decode_load(load)
    poses = poses_from_draw(DRAW.decode(lcm_seeds[DRAW.type_name][-1]))
    envelopes = [envelope.encode(request) for request in load_requests(scene)]
    envelopes.append(envelope.encode(draw_request(poses)))
    return {
        VIEWER2_COMMS.type_name: envelopes,
        "ign.Pose_V": [pose_v(poses).SerializeToString()],
        "ign.Model": [model(scene.with_poses(poses)).SerializeToString()],
        "gltf": [write_gltf(scene.with_poses(poses))],
    }


def render_form(scene: Scene) -> bytes:
    """A colour render request as RenderEngineGltfClient posts it (its form's fields), with the
    captured scene as its glTF and a camera: the Content-Type line, then the body."""
    document = json.loads(write_gltf(scene))
    document["cameras"] = [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.01, "zfar": 10}}]
    document["nodes"].append({"camera": 0, "matrix": [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 3, 1]})
    document["scenes"][0]["nodes"].append(len(document["nodes"]) - 1)
    gltf = json.dumps(document).encode()
    fields = {"scene": gltf, "scene_sha256": hashlib.sha256(gltf).hexdigest().encode(), "image_type": b"color",
              "width": b"16", "height": b"12", "near": b"0.01", "far": b"10", "focal_x": b"14", "focal_y": b"14",
              "center_x": b"7.5", "center_y": b"5.5"}  # fmt: skip
    boundary = "fuzzboundary"
    body = b"".join(
        f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'.encode() + value + b"\r\n"
        for name, value in fields.items()
    )
    return f"multipart/form-data; boundary={boundary}\n".encode() + body + f"--{boundary}--\r\n".encode()


def zenoh_seeds() -> Seeds:
    """rmw_zenoh's data keys, liveliness tokens and attachments, as the Zenoh transport writes them."""
    from viewer_bridge.transports.zenoh import keys

    node = keys.NodeName("viewer_bridge", "/sim1")
    tokens, data_keys = [keys.Token(0, "0f1e2d3c", 0, 0, keys.NODE, node).key()], []
    for index, name in enumerate(("geometry_msgs/msg/PoseArray", "tf2_msgs/msg/TFMessage")):
        kind = keys.topic_type(name)
        data_keys.append(keys.data_key(7, "/drake/poses", kind).encode())
        entity = keys.TopicEntity(
            "/sim1/drake/poses", kind.dds_name, kind.hash, keys.TokenQos(index == 0, True, False, 1)
        )
        tokens.append(keys.Token(7, "0f1e2d3c", 0, index + 1, keys.PUBLISHER, node, entity).key())
    return {
        "rmw_zenoh.data_key": data_keys,
        "rmw_zenoh.token": [token.encode() for token in tokens],
        "rmw_zenoh.attachment": [keys.attachment(12, 1_700_000_000_000_000_000, keys.gid(tokens[1]))],
    }


def foxglove_seeds() -> Seeds:
    """What Foxglove clients send: control messages and message data, as masked frames (whole,
    fragmented, past the size limit, with a ping between fragments) and as `client_frames`
    records; handshakes with and without an Origin; allowed-origin entries with origins."""
    from tests.fuzz.targets import FOXGLOVE_MAX_MESSAGE

    channel = {
        "id": 1,
        "topic": "/lcm_in/IIWA_COMMAND",
        "encoding": "json",
        "schemaName": "drake_lcm_msgs/LcmtIiwaCommand",
    }
    texts = [
        json.dumps({"op": "advertise", "channels": [channel, {**channel, "id": 2, "topic": "/cmd_vel"},
                                                    {**channel, "id": 3, "encoding": "protobuf"}]}),
        json.dumps({"op": "advertise", "channels": [{**channel, "id": index} for index in range(6)]}),
        json.dumps({"op": "unadvertise", "channelIds": [1, 2, "x"]}),
        json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 1}]}),
        json.dumps({"op": "unsubscribe", "subscriptionIds": [1]}),
        '{"op": "advertise", "channels": [{"id": 1,',  # cut off
        "[1, 2]",
    ]  # fmt: skip
    data = b"\x01" + (1).to_bytes(4, "little") + b'{"utime": 7}'
    records = [bytes([0x81]) + len(text).to_bytes(2, "little") + text.encode() for text in texts]
    # on the channel just advertised
    records.insert(1, bytes([0x82]) + len(data).to_bytes(2, "little") + data)
    records.append(
        bytes([0x01])
        + (5).to_bytes(2, "little")
        + b"\x00\x00\x00\x00{"
        + bytes([0x89, 0, 0])
        # fragments, a ping between
        + bytes([0x80])
        + (5).to_bytes(2, "little")
        + b"\x00\x00\x00\x00}"
    )
    big = b"\x01\x01\x00\x00\x00" + b"x" * FOXGLOVE_MAX_MESSAGE
    records.append(bytes([0x82]) + len(big).to_bytes(2, "little") + big)
    records.append(bytes([0xC1]) + (4).to_bytes(2, "little") + b"abcd")  # compressed (RSV1)
    every = b"".join(records)
    return {
        "foxglove_client_messages": [b"\x00" + record for record in records] + [b"\x03" + every],
        "foxglove_client_stream": [b"\x00" + _frames(record) for record in records]
        + [b"\x10" + _frames(every)],
        "foxglove_sdk_stream": [b"\x00" + _sdk_frames(texts, data), b"\x06" + _sdk_frames(texts, data)],
        "foxglove_handshake": [
            b"\x40" + _request(origin)
            for origin in (
                None,
                "https://app.foxglove.dev",
                "http://localhost:3000",
                "https://evil.example",
                "https://viewer.lab.example",
                "http://[::1]:8080",
            )
        ],  # fmt: skip
        "foxglove_slow_handshake": [
            _trickled(_request(None), 1, 0),  # all at once
            _trickled(_request("https://evil.example"), 7, 3),  # a few bytes every 0.3 s: in time
            _trickled(_request(None), 1, 1),  # a byte every 0.1 s: past the deadline
            _trickled(_request(None)[:-2], 64, 0),  # closed before its blank line
        ],
        "origin_match": [
            b"https://*.lab.example\0https://viewer.lab.example",
            b"http://[::1]:*\0http://[::1]:8080",
            b"*\0https://evil.example/x",
            b"https://*:*\0HTTPS://A:1",
        ],  # fmt: skip
    }


def _sdk_frames(texts: list[str], data: bytes) -> bytes:
    """What the SDK sends a client: text messages (a refused subscription's status among them)
    and message data, as unmasked frames (a 16-bit length for the longer ones)."""
    refused = json.dumps({"op": "status", "level": 2, "message": "Unknown channel ID: 2"})
    frames = b""
    for opcode, payload in [(0x81, text.encode()) for text in [*texts, refused]] + [(0x82, data)]:
        length = len(payload)
        frames += bytes([opcode]) + (
            bytes([length]) if length < 126 else bytes([126]) + length.to_bytes(2, "big")
        )
        frames += payload
    return frames


def _frames(records: bytes) -> bytes:
    from tests.fuzz.targets import client_frames

    return client_frames(records)


def _trickled(request: bytes, size: int, delay: int) -> bytes:
    """`request` as foxglove_slow_handshake's records: reads of `size` bytes, `delay` x 0.1 s apart."""
    return b"".join(bytes([delay, len(part)]) + part for part in (request[at : at + size]
                    for at in range(0, len(request), size)))  # fmt: skip


def _request(origin: str | None) -> bytes:
    lines = ["GET / HTTP/1.1", "Host: 127.0.0.1:8765", "Upgrade: websocket", "Connection: Upgrade",
             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==", "Sec-WebSocket-Version: 13",
             "Sec-WebSocket-Protocol: foxglove.websocket.v1, foxglove.sdk.v1"]  # fmt: skip
    return "\r\n".join(lines + ([f"Origin: {origin}"] if origin else []) + ["", ""]).encode()


def ros_cdr_seeds() -> list[bytes]:
    """CDR of each of the ROS 2 target's types (a type-choosing byte, then the CDR), as
    mcap-ros2-support writes it (the test bag's messages) and, for the wstrings, as Fast DDS does."""
    from tests.fuzz.targets import ROS_TYPES
    from tests.lcmcodec.ros_bag import SAMPLES
    from tests.lcmcodec.test_ros_cdr import note_cdr, serialized

    seeds = [bytes([ROS_TYPES.index("my_robot/msg/Note")]) + note_cdr()]
    for _, ros_type, message in SAMPLES:
        if ros_type in ROS_TYPES:
            seeds.append(bytes([ROS_TYPES.index(ros_type)]) + serialized(ros_type, message))
    return seeds


def lcm_type_seeds() -> Seeds:
    """The `.lcm` files of the project and of the test corpus; for the generic transcoder, an
    empty and a filled message of each of its types (a type-choosing byte, then the body)."""
    from tests.fuzz.targets import _CORPUS, _GENERIC, BACK_TYPES, GENERIC_TYPES

    schemas = sorted(SCHEMA_DIR.glob("*.lcm")) + sorted(_CORPUS.rglob("*.lcm"))
    messages: list[bytes] = []
    for choice, name in enumerate(GENERIC_TYPES):
        codecs = _GENERIC.codecs(name)  # the type's and its nested types', generated together
        codec = codecs[name]
        for message in (codec.message_class(), _filled(name, codecs)):
            messages.append(bytes([choice]) + codec.encode(message)[8:])
    back_cdr, back_json = [], []
    for choice, name in enumerate(BACK_TYPES):
        known = _GENERIC.get(name)
        codecs = _GENERIC.codecs(name)
        for message in (codecs[name].message_class(), _filled(name, codecs)):
            back_cdr.append(bytes([choice]) + known.to_cdr(codecs[name].encode(message)))
        back_json.append(bytes([128 + choice]) + b"{}")
        back_json.append(bytes([choice]) + bytes([7, 9, 0, 1, 2, 3, 6, 2]) + bytes(8) + bytes([8, 8]))
    iiwa = BACK_TYPES.index("drake.lcmt_iiwa_command")
    back_json.append(
        bytes([128 + iiwa]) + b'{"utime": 5, "joint_position": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]}'
    )
    return {"lcm_schema": [path.read_bytes() for path in schemas], "lcm_generic": messages,
            "lcm_back_cdr": back_cdr, "lcm_back_json": back_json}  # fmt: skip


def _filled(type_name: str, codecs: dict[str, StructCodec]) -> LcmMessage:
    """A message of `type_name` whose variable arrays hold two elements (length members set to 2)."""
    codec = codecs[type_name]
    message = codec.message_class()
    lengths = {dim.size for member in codec.definition.members for dim in member.dims if dim.is_variable}
    for member in codec.definition.members:
        if member.name in lengths:
            setattr(message, member.name, 2)
        elif member.dims:
            shape = [2 if dim.is_variable else dim.count for dim in member.dims]
            setattr(message, member.name, _full(shape, member.type_name, codecs))
    return message


def _full(shape: list[int], type_name: str, codecs: dict[str, StructCodec]) -> object:
    if type_name == "byte" and len(shape) == 1:
        return b"\x01" * shape[0]
    if len(shape) > 1:
        return [_full(shape[1:], type_name, codecs) for _ in range(shape[0])]
    leaves: dict[str, object] = {"string": "ab", "double": 1.5, "float": 0.5, "boolean": True}
    if type_name in leaves or type_name.endswith("_t") and type_name.startswith("int"):
        return [leaves.get(type_name, 1) for _ in range(shape[0])]
    return [_filled(type_name, codecs) for _ in range(shape[0])]


def discovery_seeds() -> list[bytes]:
    """Discovery datagrams of every message type (and one no peer knows) in both wire versions,
    naming what the fuzzed node subscribes to and advertises, plain, relayed and not to relay."""
    seeds = []
    for version in (WIRE_VERSION, STATISTICS_VERSION):
        for kind in [*range(10), 12]:
            for relay, no_relay in ((False, False), (True, False), (False, True)):
                message = Record(version=version, process_uuid="fuzz-peer", type=kind)
                message.flags.relay, message.flags.no_relay = relay, no_relay
                if kind == Record.SUBSCRIBE:
                    message.sub.topic = DISCOVERY_ADVERTISED
                elif kind != Record.HEARTBEAT:
                    publisher = message.pub
                    publisher.topic, publisher.address = DISCOVERY_SUBSCRIBED, "tcp://127.0.0.1:40001"
                    publisher.process_uuid, publisher.node_uuid = "fuzz-peer", "fuzz-node"
                    publisher.scope = Record.Publisher.ALL
                    publisher.msg_pub.msg_type = (
                        "ignition.msgs.Pose_V" if version == WIRE_VERSION else "gz.msgs.Pose_V"
                    )
                seeds.append(datagram(message))
    anything = Record(version=WIRE_VERSION, process_uuid="fuzz-peer", type=Record.ADVERTISE)
    anything.pub.topic, anything.pub.address = DISCOVERY_ANY, "tcp://[::1]:40002"
    anything.pub.msg_pub.msg_type = "my.msgs.Thing"
    return [*seeds, datagram(anything)]


def mcap_seeds() -> list[bytes]:
    """Small MCAP files of JointStates after their magic bytes (the target adds it): chunks of
    every compression and none, messages outside any chunk, and a chunk that declares 100 bytes
    and inflates to 1 MiB."""
    from tests.cli.test_bag_to_lcm import joints_mcap_as, mcap_with_bomb, zstd_bomb

    files = []
    with tempfile.TemporaryDirectory() as folder:
        for compression in ("", "lz4", "zstd", "unchunked"):
            joints_mcap_as(Path(folder) / "bag.mcap", compression, 6, chunk_size=256)
            files.append((Path(folder) / "bag.mcap").read_bytes())
        mcap_with_bomb(Path(folder) / "bomb.mcap", "zstd", zstd_bomb(1 << 20))
        files.append((Path(folder) / "bomb.mcap").read_bytes())
    return [data[len(b"\x89MCAP0\r\n") :] for data in files]


def meldis_seeds() -> Seeds:
    """Contact results and point clouds (what meldis shows), as the bridge writes them."""
    from tests.formats.drake.oracle import contact_results_to_lcm
    from viewer_bridge.examples.scenes import demo_contact_results
    from viewer_bridge.formats.drake.point_cloud import cloud_to_lcm
    from viewer_bridge.formats.ros.point_cloud import cloud_to_cdr
    from viewer_bridge.model.scene import PointCloud, StampedPointCloud

    points = np.arange(30, dtype=np.float64).reshape(10, 3) / 10
    clouds = [StampedPointCloud(PointCloud(points), "world", 1000),
              StampedPointCloud(PointCloud(points, np.linspace(0, 1, 30).reshape(10, 3)), "camera", 2000)]  # fmt: skip
    return {
        "drake.lcmt_contact_results_for_viz": [contact_results_to_lcm(demo_contact_results()).encode()],
        "drake.lcmt_point_cloud": [cloud_to_lcm(cloud) for cloud in clouds],
        "sensor_msgs/PointCloud2": [cloud_to_cdr(cloud) for cloud in clouds],
    }


def image_seeds() -> Seeds:
    """Small camera images as the bridge writes them: Drake's rgb, depth and label ports (raw and
    zlib), a PNG and a JPEG image, and sensor_msgs/Image of each encoding the way back reads."""
    import io

    from PIL import Image as PilImage

    from viewer_bridge.formats.drake.image import images_to_lcm
    from viewer_bridge.formats.ros.image import LAYOUTS, image_to_cdr
    from viewer_bridge.lcmcodec.codecs import IMAGE_ARRAY
    from viewer_bridge.model.image import Image, Layout

    rgba = np.arange(48, dtype=np.uint8).reshape(3, 4, 4)
    camera = [Image("rgb", 1000, Layout.RGBA, rgba),
              Image("depth", 1000, Layout.DEPTH, np.arange(12, dtype=np.uint16).reshape(3, 4, 1) * 500),
              Image("label", 1000, Layout.LABEL, np.arange(12, dtype=np.int16).reshape(3, 4, 1) % 3)]  # fmt: skip
    arrays = [images_to_lcm(camera, 1000), images_to_lcm(camera, 1000, compress=True)]
    for file_format, compression in (("PNG", 3), ("JPEG", 2)):
        out = io.BytesIO()
        PilImage.fromarray(rgba[:, :, :3]).save(out, file_format)
        message = IMAGE_ARRAY.decode(images_to_lcm([Image("rgb", 0, Layout.RGB, rgba[:, :, :3])], 0))
        message.images[0].data, message.images[0].size = out.getvalue(), len(out.getvalue())
        message.images[0].compression_method = compression
        arrays.append(IMAGE_ARRAY.encode(message))
    ros = [image_to_cdr(Image(name, 0, layout, np.zeros((2, 3, layout.channels), dtype)), "cam", (1, 0))
           for name, (layout, dtype) in LAYOUTS.items()]  # fmt: skip
    return {"drake.lcmt_image_array": arrays, "sensor_msgs/Image": ros}
