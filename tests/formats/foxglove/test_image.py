"""Foxglove's RawImage, CompressedImage and CameraCalibration: read back by foxglove-schemas-protobuf."""

from __future__ import annotations

import numpy as np
import pytest
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

from tests.formats.ros.test_image import padded
from tests.pixels import sample_pixels
from viewer_bridge.formats.foxglove.image import camera_calibration, compressed_image, raw_image
from viewer_bridge.model.image import EncodedImage, Image, Intrinsics, Layout

IMAGES = {
    "rgba8": (Image("rgb", 0, Layout.RGBA, sample_pixels(np.uint8, (3, 5, 4))), "<u1"),
    "16UC1": (Image("depth", 0, Layout.DEPTH, sample_pixels(np.uint16, (3, 5, 1)).astype(">u2")), "<u2"),
    "16UC1 (labels: the panel has no 16SC1)": (
        Image("label", 0, Layout.LABEL, padded(sample_pixels(np.int16, (3, 5, 1)), 4)), "<i2"),
    "32FC1": (Image("depth", 0, Layout.DEPTH, sample_pixels(np.float32, (3, 5, 1))), "<f4"),
    "bgr8": (Image("rgb", 0, Layout.BGRA, sample_pixels(np.uint8, (3, 5, 4))).without_alpha(), "<u1"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(IMAGES))
def test_raw_image_reads_back_little_endian_with_its_rows_back_to_back(case: str) -> None:
    image, dtype = IMAGES[case]
    message = RawImage()
    message.ParseFromString(raw_image(image, "left", (12, 5)))
    assert (message.timestamp.seconds, message.timestamp.nanos, message.frame_id) == (12, 5, "left")
    assert (message.width, message.height, message.encoding) == (5, 3, case.split()[0])
    assert message.step == 5 * image.pixels.shape[2] * np.dtype(dtype).itemsize
    np.testing.assert_array_equal(
        np.frombuffer(message.data, dtype).reshape(image.pixels.shape), image.pixels
    )


def test_compressed_image_and_calibration_read_back() -> None:
    encoded = EncodedImage("rgb", 0, Layout.RGB, 4, 3, "png", memoryview(b"\x89PNG..."))
    message = CompressedImage()
    message.ParseFromString(compressed_image(encoded, "left", (1, 2)))
    assert (message.format, message.data, message.frame_id, message.timestamp.nanos) == (
        "png",
        b"\x89PNG...",
        "left",
        2,
    )
    calibration = CameraCalibration()
    calibration.ParseFromString(
        camera_calibration(Intrinsics(640, 480, 500.0, 510.0, 319.5, 239.5), "left", (3, 0))
    )
    assert (calibration.width, calibration.height, calibration.frame_id) == (640, 480, "left")
    assert list(calibration.K) == [500.0, 0.0, 319.5, 0.0, 510.0, 239.5, 0.0, 0.0, 1.0]
    assert list(calibration.P) == [500.0, 0.0, 319.5, 0.0, 0.0, 510.0, 239.5, 0.0, 0.0, 0.0, 1.0, 0.0]
    assert list(calibration.D) == [0.0] * 5 and calibration.distortion_model == "plumb_bob"
