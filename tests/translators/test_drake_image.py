"""The camera image translators, called as the router calls them (and through a RouteRunner)."""

from __future__ import annotations

import io
import re
import time
import zlib
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest
from PIL import Image as PilImage
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import CameraInfo, CompressedImage
from sensor_msgs.msg import Image as RosImage

from tests.drake_images import publish_with_drake, read_with_drake
from tests.formats.drake.test_image import lcm_array, lcm_image, sample_pixels
from tests.formats.ros.test_image import rclpy_image
from viewer_bridge.cli.log_convert import convert
from viewer_bridge.config.bridge import Route, destination_name, load_config
from viewer_bridge.errors import ConfigError, DecodeError, EncodeError
from viewer_bridge.formats.ros.image import LAYOUTS
from viewer_bridge.model.skipped import collecting
from viewer_bridge.shared import Shared
from viewer_bridge.translators import TRANSLATORS
from viewer_bridge.transports.base import CallPublisher, Received
from viewer_bridge.transports.lcm import LcmEvent, write_log

RGBA = sample_pixels(np.uint8, (6, 8, 4))
DEPTH = sample_pixels(np.uint16, (6, 8, 1))
LABEL = sample_pixels(np.int16, (6, 8, 1))
CAMERA = [("rgb", "rgba8", RGBA), ("depth", "depth16", DEPTH), ("label", "label16", LABEL)]


def ros_image(data: bytes) -> tuple[Any, np.ndarray]:
    message = deserialize_message(data, RosImage)
    dtype = {"rgba8": "u1", "rgb8": "u1", "16UC1": "<u2", "16SC1": "<i2", "32FC1": "<f4"}[message.encoding]
    pixels = np.frombuffer(bytes(message.data), dtype).reshape(message.height, message.width, -1)
    return message, pixels


def test_each_port_of_a_camera_becomes_an_image_topic_added_as_it_appears() -> None:
    translator = TRANSLATORS.get("drake_images_to_ros")({})
    assert translator.outputs == ()
    received = Received(
        "DRAKE_RGBD_CAMERA_IMAGES_wrist", publish_with_drake(CAMERA, 2.5, compress=True), 7_000_000
    )
    translator.observe(received)
    assert [output.suffix for output in translator.outputs] == ["/rgb/image", "/depth/image", "/label/image"]
    assert {output.type.name for output in translator.outputs} == {"sensor_msgs/msg/Image"}
    out = translator.translate(received)
    assert [index for index, _ in out] == [0, 1, 2]
    for (_, data), expected, encoding in zip(
        out, (RGBA, DEPTH, LABEL), ("rgba8", "16UC1", "16SC1"), strict=True
    ):
        message, pixels = ros_image(data)
        assert message.encoding == encoding and message.header.frame_id == "wrist"
        assert (message.header.stamp.sec, message.header.stamp.nanosec) == (7, 0)  # receive time by default
        np.testing.assert_array_equal(pixels, expected)


def test_options_drop_alpha_metres_sim_stamps_frame_and_camera_info() -> None:
    options = {"drop_alpha": True, "depth": "32FC1", "stamp": "sim", "frame_id": "camera_optical",
               "camera_info": {"width": 8, "height": 6, "fov_y": 45}}  # fmt: skip
    translator = TRANSLATORS.get("drake_images_to_ros")(options)
    depth = DEPTH.copy()
    depth[0, 0], depth[0, 1] = 0, 65535
    data = publish_with_drake([("rgb", "rgba8", RGBA), ("depth", "depth16", depth)], 2.5, compress=True)
    out = dict(translator.translate(Received("DRAKE_RGBD_CAMERA_IMAGES", data)))
    suffixes = [output.suffix for output in translator.outputs]
    assert suffixes == ["/rgb/image", "/rgb/camera_info", "/depth/image", "/depth/camera_info"]
    rgb, rgb_pixels = ros_image(out[0])
    assert rgb.encoding == "rgb8" and rgb.header.frame_id == "camera_optical"
    assert (rgb.header.stamp.sec, rgb.header.stamp.nanosec) == (2, 500_000_000)
    np.testing.assert_array_equal(rgb_pixels, RGBA[:, :, :3])
    metres = ros_image(out[2])[1]
    assert metres[0, 0, 0] == -np.inf and metres[0, 1, 0] == np.inf
    drake = read_with_drake(data)["depth_image"]  # Drake's own millimetres -> metres
    np.testing.assert_array_equal(metres.ravel()[2:], drake.ravel()[2:])
    info = deserialize_message(out[1], CameraInfo)
    assert (info.width, info.height, info.header.frame_id) == (8, 6, "camera_optical")
    assert info.k[0] == pytest.approx(3 / np.tan(np.radians(22.5))) and info.k[2] == 3.5
    assert out[3] == translator.translate(Received("DRAKE_RGBD_CAMERA_IMAGES", data))[3][1]


def test_compressed_passes_drakes_png_through_and_encodes_the_rest() -> None:
    translator = TRANSLATORS.get("drake_images_to_ros")({"compressed": "png"})
    png = io.BytesIO()
    PilImage.fromarray(RGBA).save(png, "PNG")
    sent_as_png = lcm_image("rgb", RGBA, data=png.getvalue(), compression_method=3)
    raw_depth = lcm_image("depth", DEPTH, pixel_format=5, channel_type=3)
    out = translator.translate(Received("DRAKE_RGBD_CAMERA_IMAGES_x", lcm_array(sent_as_png, raw_depth)))
    suffixes = [translator.outputs[index].suffix for index, _ in out]
    assert suffixes == ["/rgb/image", "/rgb/image/compressed", "/depth/image", "/depth/image/compressed"]
    passed = deserialize_message(out[1][1], CompressedImage)
    assert passed.format == "png" and bytes(passed.data) == png.getvalue()  # as Drake sent it
    np.testing.assert_array_equal(ros_image(out[0][1])[1], RGBA)
    encoded = deserialize_message(out[3][1], CompressedImage)
    decoded = np.asarray(PilImage.open(io.BytesIO(bytes(encoded.data))))
    assert encoded.format == "png"
    np.testing.assert_array_equal(decoded.reshape(DEPTH.shape), DEPTH)


def test_a_bad_image_is_counted_on_the_route_and_the_others_go_out() -> None:
    from viewer_bridge.router.flow import Message
    from viewer_bridge.router.runner import RouteRunner

    route = Route.model_validate(
        {"name": "cameras", "source": {"transport": "lcm", "name": "DRAKE_RGBD_CAMERA_IMAGES_(.+)"},
         "translator": "drake_images_to_ros", "destination": {"transport": "ros", "name": "drake/cameras/{1:topic}"},
         "lazy": True}
    )  # fmt: skip
    published: dict[str, list[bytes]] = {}
    listeners = 0

    def publisher(name: str, output: Any) -> CallPublisher:
        return CallPublisher(published.setdefault(name, []).append, lambda: listeners)

    runner = RouteRunner(route, lambda: TRANSLATORS.get("drake_images_to_ros")({}), publisher)
    broken = lcm_image("depth", DEPTH, pixel_format=5, channel_type=3, data=b"short")
    data = lcm_array(
        lcm_image("rgb", RGBA), broken, lcm_image("label", LABEL, pixel_format=6, channel_type=2)
    )
    match = re.fullmatch(route.source.name, "DRAKE_RGBD_CAMERA_IMAGES_left")
    assert match is not None
    runner.handle(Message(Received("DRAKE_RGBD_CAMERA_IMAGES_left", data), match))
    assert runner.stats.idle_skipped == 1 and not any(published.values())  # lazy: nobody listens yet
    assert set(published) == {f"drake/cameras/left/{port}/image" for port in ("rgb", "depth", "label")}
    listeners = 1
    deadline = time.monotonic() + 60
    while not published["drake/cameras/left/rgb/image"] and time.monotonic() < deadline:
        runner.catch_up()
        time.sleep(0.01)
    assert (
        len(published["drake/cameras/left/rgb/image"])
        == len(published["drake/cameras/left/label/image"])
        == 1
    )
    assert not published["drake/cameras/left/depth/image"]
    assert runner.stats.errors == {"DecodeError": 1} and runner.stats.messages_out == 2


def test_an_array_that_is_no_array_is_an_error_of_translate_not_of_observe() -> None:
    translator = TRANSLATORS.get("drake_images_to_ros")({})
    received = Received("DRAKE_RGBD_CAMERA_IMAGES", b"nonsense")
    translator.observe(received)
    with pytest.raises(DecodeError), collecting():
        translator.translate(received)


def test_the_default_config_names_the_camera_topics() -> None:
    routes = {route.name: route for route in load_config(None).routes}
    for route_name, channel, topic in [
        ("camera_images", "DRAKE_RGBD_CAMERA_IMAGES_preview_camera", "drake/cameras/preview_camera"),
        ("camera_images", "DRAKE_RGBD_CAMERA_IMAGES_0", "drake/cameras/n0"),
        ("camera_images_unnamed", "DRAKE_RGBD_CAMERA_IMAGES", "drake/cameras/camera"),
    ]:
        route = routes[route_name]
        match = re.fullmatch(route.source.name, channel)
        assert match is not None and destination_name(route.destination.name, match) == topic
        assert route.lazy and route.rate.policy == "latest"
    assert re.fullmatch(routes["camera_images"].source.name, "DRAKE_RGBD_CAMERA_IMAGES") is None


def test_camera_info_options_are_checked_when_the_config_loads(tmp_path: Any) -> None:
    path = tmp_path / "bridge.yaml"
    path.write_text(
        "routes:\n  - name: c\n    source: {transport: lcm, name: DRAKE_RGBD_CAMERA_IMAGES}\n"
        "    translator: drake_images_to_ros\n    destination: {transport: ros, name: cam}\n"
        "    options: {camera_info: {width: 640, height: 480, fov_y: 45, fx: 500, fy: 500}}\n"
    )
    with pytest.raises(ConfigError, match="give either fov_y"):
        load_config(path)


def ros_test_image(encoding: str) -> np.ndarray:
    """Pixels for an encoding; 32FC1 with REP 117's too close, too far and no return."""
    layout, dtype = LAYOUTS[encoding]
    pixels = sample_pixels(dtype, (5, 4, layout.channels))
    if encoding == "32FC1":
        pixels[0, 0], pixels[0, 1], pixels[0, 2] = -np.inf, np.inf, np.nan
    return pixels


def assert_drake_reads(encoding: str, pixels: np.ndarray, data: bytes) -> None:
    """Drake's LcmImageArrayToImages reads colour (as RGBA), depth (as metres) and labels; grey and
    Bayer images, which it has no output for, are read with Drake's lcmt_image_array class and zlib."""
    layout, dtype = LAYOUTS[encoding]
    (image,) = drake_lcmtypes.lcmt_image_array.decode(data).images
    drake = read_with_drake(data)
    if encoding in ("rgb8", "rgba8", "bgr8", "bgra8"):
        rgb = pixels[:, :, [2, 1, 0, 3][: layout.channels]] if encoding.startswith("bgr") else pixels
        assert image.header.frame_name == "rgb"
        np.testing.assert_array_equal(drake["color_image"][:, :, : layout.channels], rgb)
        if layout.channels == 3:
            assert (drake["color_image"][:, :, 3] == 255).all()
    elif encoding == "16UC1":
        np.testing.assert_array_equal(drake["depth_image"], (pixels / 1e3).astype(np.float32))
    elif encoding == "32FC1":
        expected = pixels.copy()
        expected[0, 0], expected[0, 2] = 0.0, np.inf  # Drake's too close; no return as too far
        np.testing.assert_array_equal(drake["depth_image"], expected)
    elif encoding == "16SC1":
        np.testing.assert_array_equal(drake["label_image"], pixels)
    else:
        rows = np.frombuffer(zlib.decompress(image.data), dtype.newbyteorder("<"))
        np.testing.assert_array_equal(rows.reshape(pixels.shape), pixels)
        assert image.header.frame_name == layout.value


@pytest.mark.parametrize("encoding", sorted(LAYOUTS))
def test_a_ros_image_becomes_an_array_drake_reads(encoding: str) -> None:
    pixels = ros_test_image(encoding)
    translator = TRANSLATORS.get("ros_image_to_drake")({})
    received = Received("/drake_in/camera/image", rclpy_image(encoding, pixels, 3, True))
    if encoding in ("rgb16", "rgba16", "bgr16", "bgra16"):
        with pytest.raises(EncodeError, match="16-bit colour"):
            translator.translate(received)
        return
    ((_, data),) = translator.translate(received)
    message = drake_lcmtypes.lcmt_image_array.decode(data)
    assert message.header.frame_name == "cam" and message.header.utime == 3_500_000
    assert message.images[0].compression_method == drake_lcmtypes.lcmt_image.COMPRESSION_METHOD_ZLIB
    assert_drake_reads(encoding, pixels, data)


def test_uncompressed_on_request_as_drakes_class_reads_it() -> None:
    pixels = ros_test_image("16UC1")
    translator = TRANSLATORS.get("ros_image_to_drake")({"compress": False, "name": "range"})
    ((_, data),) = translator.translate(Received("/x", rclpy_image("16UC1", pixels)))
    (image,) = drake_lcmtypes.lcmt_image_array.decode(data).images
    assert image.compression_method == 0 and image.header.frame_name == "range"
    np.testing.assert_array_equal(np.frombuffer(image.data, "<u2").reshape(pixels.shape), pixels)


def test_bad_ros_image_bytes_are_a_decode_error() -> None:
    with pytest.raises(DecodeError, match="encoding"):
        TRANSLATORS.get("ros_image_to_drake")({}).translate(
            Received("/x", rclpy_image("yuv422", np.zeros((2, 2, 2), np.uint8)))
        )


def test_foxglove_gets_raw_images_stamped_with_sim_time_and_calibrations() -> None:
    from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

    translator = TRANSLATORS.get("drake_images_to_foxglove")(
        {"camera_info": {"width": 8, "height": 6, "fov_y": 45}}, shared=Shared(time="sim")
    )
    out = translator.translate(
        Received("DRAKE_RGBD_CAMERA_IMAGES_top", publish_with_drake(CAMERA, 2.5, compress=True))
    )
    suffixes = [translator.outputs[index].suffix for index, _ in out]
    assert suffixes == [
        f"/{port}/{kind}" for port in ("rgb", "depth", "label") for kind in ("image", "calibration")
    ]
    assert {output.type.name for output in translator.outputs} == {
        "foxglove.RawImage",
        "foxglove.CameraCalibration",
    }
    images = [
        RawImage.FromString(data) for index, data in out if translator.outputs[index].suffix.endswith("image")
    ]
    for message, expected, dtype in zip(images, (RGBA, DEPTH, LABEL), ("u1", "<u2", "<i2"), strict=True):
        assert message.frame_id == "top" and (message.timestamp.seconds, message.timestamp.nanos) == (
            2,
            500_000_000,
        )
        np.testing.assert_array_equal(np.frombuffer(message.data, dtype).reshape(expected.shape), expected)
    assert [message.encoding for message in images] == ["rgba8", "16UC1", "16UC1"]
    calibration = CameraCalibration.FromString(out[1][1])
    assert (calibration.width, calibration.height, calibration.K[2]) == (8, 6, 3.5)


@pytest.mark.parametrize("schema", ["ros2", "foxglove"])
def test_convert_writes_every_port_of_a_logged_camera_with_its_pixels(schema: str, tmp_path: Path) -> None:
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    log, out = tmp_path / "cameras.lcmlog", tmp_path / "cameras.mcap"
    array = publish_with_drake(CAMERA, 2.5, compress=True)
    write_log(log, [LcmEvent("DRAKE_RGBD_CAMERA_IMAGES_wrist", array, 1_000_000)])
    topics = [f"/drake/cameras/wrist/{port}/image" for port, _, _ in CAMERA]
    assert convert(log, out, load_config(None), progress=False, schema=schema).messages == dict.fromkeys(
        topics, 1
    )  # type: ignore[arg-type]
    with out.open("rb") as file:
        reader = make_reader(file, decoder_factories=[DecoderFactory()])
        if schema == "ros2":
            written = {channel.topic: (message.width, message.height, bytes(message.data))
                       for _, channel, _, message in reader.iter_decoded_messages()}  # fmt: skip
        else:
            written = {}
            for schema_record, channel, message in reader.iter_messages():
                assert schema_record is not None and schema_record.name == "foxglove.RawImage"
                image = RawImage()
                image.ParseFromString(message.data)
                written[channel.topic] = (image.width, image.height, bytes(image.data))
    for topic, (_, _, pixels) in zip(topics, CAMERA, strict=True):
        width, height, data = written[topic]
        assert (width, height) == (pixels.shape[1], pixels.shape[0])
        np.testing.assert_array_equal(np.frombuffer(data, pixels.dtype).reshape(pixels.shape), pixels)
