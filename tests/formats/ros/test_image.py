"""sensor_msgs Image, CompressedImage and CameraInfo CDR: the fast writers against rosbags' serialiser,
the reader against rclpy's, and the refusals."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from tests.optional import peer
from tests.pixels import sample_pixels
from viewer_bridge.errors import DecodeError, EncodeError
from viewer_bridge.formats.ros.image import (
    LAYOUTS,
    CameraInfoEncoder,
    camera_info_cdr,
    compressed_image_to_cdr,
    encoding,
    image_from_cdr,
    image_to_cdr,
)
from viewer_bridge.formats.ros.messages import make, to_cdr
from viewer_bridge.model.image import EncodedImage, Image, Intrinsics, Layout

serialization = peer("rclpy.serialization")
sensor_msgs = peer("sensor_msgs.msg")

STAMP = (12, 345_000_000)


def rosbags_image(image: Image, frame_id: str, name: str) -> bytes:
    """The reference: the same Image built field by field and serialised by rosbags."""
    rows = np.ascontiguousarray(image.pixels)
    return to_cdr(
        make(
            "sensor_msgs/msg/Image",
            header=make("std_msgs/msg/Header", stamp=make("builtin_interfaces/msg/Time", sec=STAMP[0],
                        nanosec=STAMP[1]), frame_id=frame_id),
            height=image.height, width=image.width, encoding=name, is_bigendian=int(image.big_endian),
            step=rows.shape[1] * rows.shape[2] * rows.dtype.itemsize, data=np.frombuffer(rows.tobytes(), np.uint8),
        )
    )  # fmt: skip


def padded(pixels: np.ndarray, padding: int) -> np.ndarray:
    """The same pixels as a strided view into rows `padding` bytes longer."""
    height, width, channels = pixels.shape
    row = width * channels * pixels.dtype.itemsize
    buffer = np.zeros((height, row + padding), np.uint8)
    buffer[:, :row] = np.frombuffer(pixels.tobytes(), np.uint8).reshape(height, row)
    return np.ndarray(pixels.shape, pixels.dtype, buffer, 0, (row + padding, channels * pixels.dtype.itemsize,
                                                               pixels.dtype.itemsize))  # fmt: skip


IMAGES = {
    "rgba8": Image("rgb", 0, Layout.RGBA, sample_pixels(np.uint8, (3, 5, 4))),
    "rgb8 (alpha dropped: a strided view)": Image("rgb", 0, Layout.RGBA, sample_pixels(np.uint8, (3, 5, 4))).without_alpha(),
    "bgra8": Image("rgb", 0, Layout.BGRA, sample_pixels(np.uint8, (3, 5, 4))),
    "16UC1": Image("depth", 0, Layout.DEPTH, sample_pixels(np.uint16, (3, 5, 1))),
    "16UC1 big-endian": Image("depth", 0, Layout.DEPTH, sample_pixels(np.uint16, (3, 5, 1)).astype(">u2")),
    "32FC1": Image("depth", 0, Layout.DEPTH, sample_pixels(np.float32, (3, 5, 1))),
    "16SC1 with padded rows": Image("label", 0, Layout.LABEL, padded(sample_pixels(np.int16, (3, 5, 1)), 6)),
    "mono16": Image("ir", 0, Layout.GRAY, sample_pixels(np.uint16, (3, 5, 1))),
    "bayer_rggb8": Image("raw", 0, Layout.BAYER_RGGB, sample_pixels(np.uint8, (3, 5, 1))),
    "8UC1 (a mask)": Image("mask", 0, Layout.MASK, sample_pixels(np.uint8, (3, 5, 1))),
    "64FC1 (float64 disparity)": Image("d", 0, Layout.DISPARITY, sample_pixels(np.float64, (3, 5, 1))),
    "32SC4": Image("x", 0, Layout.RGBA, sample_pixels(np.int32, (3, 5, 4))),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(IMAGES))
def test_image_cdr_is_what_rosbags_writes_and_rclpy_reads(case: str) -> None:
    image, name = IMAGES[case], case.split()[0]
    assert encoding(image) == name
    data = image_to_cdr(image, "left_camera", STAMP)
    assert data == rosbags_image(image, "left_camera", name)
    message = serialization.deserialize_message(data, sensor_msgs.Image)
    assert (message.height, message.width, message.encoding) == (3, 5, name)
    assert message.header.frame_id == "left_camera" and message.header.stamp.nanosec == STAMP[1]
    dtype = image.pixels.dtype
    got = np.frombuffer(bytes(message.data), dtype).reshape(image.pixels.shape)
    np.testing.assert_array_equal(got, image.pixels)


def test_uint32_channels_have_no_ros_encoding() -> None:
    with pytest.raises(EncodeError, match="image 'x': ROS has no encoding for uint32"):
        encoding(Image("x", 0, Layout.GRAY, np.zeros((1, 1, 1), np.uint32)))


def test_compressed_image_cdr_is_what_rosbags_writes() -> None:
    jpeg = b"\xff\xd8 some jpeg \xff\xd9"
    encoded = EncodedImage("rgb", 0, Layout.RGB, 4, 3, "jpeg", memoryview(jpeg))
    reference = make("sensor_msgs/msg/CompressedImage", format="jpeg", data=np.frombuffer(jpeg, np.uint8),
                     header=make("std_msgs/msg/Header", frame_id="cam",
                                 stamp=make("builtin_interfaces/msg/Time", sec=STAMP[0], nanosec=STAMP[1])))  # fmt: skip
    assert compressed_image_to_cdr(encoded, "cam", STAMP) == to_cdr(reference)


def test_intrinsics_from_a_field_of_view_are_drakes() -> None:
    from pydrake.systems.sensors import CameraInfo

    for width, height, fov_y in ((640, 480, 45.0), (1280, 720, 60.0), (33, 17, 90.0)):
        drake = CameraInfo(width, height, math.radians(fov_y))
        ours = Intrinsics.from_fov(width, height, fov_y)
        assert (ours.fx, ours.fy, ours.cx, ours.cy) == pytest.approx(
            (drake.focal_x(), drake.focal_y(), drake.center_x(), drake.center_y()), rel=1e-12
        )
    both = Intrinsics.from_fov(640, 480, 45.0, 60.0)
    assert both.fx == pytest.approx(320 / math.tan(math.radians(30))) and both.fy != both.fx


def test_camera_info_is_a_pinhole_without_distortion_with_each_stamp() -> None:
    intrinsics = Intrinsics(640, 480, 500.0, 510.0, 319.5, 239.5)
    encoder = CameraInfoEncoder(intrinsics, "cam")
    data = encoder.encode(STAMP)
    assert data == camera_info_cdr(intrinsics, "cam", STAMP)
    message: Any = serialization.deserialize_message(data, sensor_msgs.CameraInfo)
    assert (message.width, message.height, message.distortion_model) == (640, 480, "plumb_bob")
    assert list(message.d) == [0.0] * 5
    assert list(message.k) == [500.0, 0.0, 319.5, 0.0, 510.0, 239.5, 0.0, 0.0, 1.0]
    assert list(message.r) == [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    assert list(message.p) == [500.0, 0.0, 319.5, 0.0, 0.0, 510.0, 239.5, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert (message.header.stamp.sec, message.header.frame_id) == (12, "cam")


def rclpy_image_bytes(**fields: Any) -> bytes:
    """An rclpy `sensor_msgs/Image` of these fields, serialised by rclpy."""
    return bytes(serialization.serialize_message(sensor_msgs.Image(**fields)))


def rclpy_image(name: str, pixels: np.ndarray, step_padding: int = 0, big_endian: bool = False) -> bytes:
    message = sensor_msgs.Image()
    message.header.frame_id, message.header.stamp.sec, message.header.stamp.nanosec = "cam", 3, 500_000_000
    message.height, message.width = pixels.shape[:2]
    message.encoding, message.is_bigendian = name, big_endian
    wire = pixels.astype(pixels.dtype.newbyteorder(">" if big_endian else "<"))
    rows = np.frombuffer(wire.tobytes(), np.uint8).reshape(pixels.shape[0], -1)
    rows = np.concatenate((rows, np.zeros((pixels.shape[0], step_padding), np.uint8)), axis=1)
    message.step, message.data = rows.shape[1], rows.tobytes()
    return bytes(serialization.serialize_message(message))


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_every_encoding_reads_back_in_either_byte_order_with_a_padded_step(name: str) -> None:
    layout, dtype = LAYOUTS[name]
    pixels = sample_pixels(dtype, (4, 3, layout.channels))
    for big_endian in (False, True):
        stamped = image_from_cdr(rclpy_image(name, pixels, step_padding=5, big_endian=big_endian))
        assert (stamped.frame_id, stamped.time_us) == ("cam", 3_500_000)
        image = stamped.image
        assert (image.layout, image.name, image.time_us) == (layout, layout.value, 3_500_000)
        np.testing.assert_array_equal(image.pixels, pixels)


BAD = {
    "an encoding Drake has no format for": (lambda: rclpy_image("yuv422", np.zeros((2, 2, 2), np.uint8)), "encoding",
                                            "'yuv422' has no Drake pixel format"),
    "data that is not step x height": (
        lambda: rclpy_image_bytes(height=2, width=2, encoding="rgb8", step=6, data=bytes(10)),
        "data", "10 bytes are not step 6 x height 2"),
    "not CDR": (lambda: b"\x07\x07\x00\x00", "", "not CDR"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_image_is_a_decode_error_naming_the_field(case: str) -> None:
    make_bytes, field, reason = BAD[case]
    with pytest.raises(DecodeError) as raised:
        image_from_cdr(make_bytes())
    assert raised.value.field == field and reason in str(raised.value), str(raised.value)


def test_a_step_shorter_than_a_row_is_refused() -> None:
    message = sensor_msgs.Image(height=2, width=4, encoding="mono16", step=6, data=bytes(12))
    with pytest.raises(DecodeError, match="step 6 is shorter than a row"):
        image_from_cdr(bytes(serialization.serialize_message(message)))


def test_an_empty_image_is_written() -> None:
    """bench/fuzz.py's first image finding (drake_images_to_ros): a 0 x 4 image raised TypeError
    (a memoryview of an empty array cannot be cast)."""
    empty = Image("rgb", 0, Layout.RGBA, np.zeros((0, 4, 4), np.uint8))
    message = serialization.deserialize_message(image_to_cdr(empty, "cam", STAMP), sensor_msgs.Image)
    assert (message.height, message.width, message.step, len(message.data)) == (0, 4, 16, 0)
