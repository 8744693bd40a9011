"""ROS 2's `sensor_msgs` images <-> neutral images (`viewer_bridge.model.image`), straight from and to CDR bytes.

Written: `Image` (the pixels with their rows back to back, in their own byte order:
`is_bigendian` says which, so nothing is swapped), `CompressedImage` (JPEG or PNG bytes passed on
as they came, `format` "jpeg" or "png") and `CameraInfo` (a pinhole without distortion: K, R = I,
P = [K | 0]). Read: `Image` in the encodings a Drake image has a pixel format for, strided rows
and either byte order, for the way back to Drake.

Encodings (`sensor_msgs/image_encodings.hpp`): colour and grey by name (rgb8, rgba8, bgr8, bgra8,
their 16-bit forms, mono8, mono16, bayer_*8/16); depth as 16UC1 (millimetres, REP 118) or 32FC1
(metres, REP 117), labels as 16SC1; anything else as `<bits><U|S|F>C<channels>`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from viewer_bridge.errors import DecodeError, EncodeError
from viewer_bridge.formats.ros.cdr import CdrReader, StampedTemplate
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.image import (
    NO_DISTORTION,
    NO_ROTATION,
    EncodedImage,
    Image,
    Intrinsics,
    Layout,
    Pixels,
)

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"

# Encodings by name: (encoding, layout, one channel's numpy type). Read and written alike.
_NAMED = (
    ("rgb8", Layout.RGB, "u1"), ("rgba8", Layout.RGBA, "u1"), ("bgr8", Layout.BGR, "u1"),
    ("bgra8", Layout.BGRA, "u1"), ("rgb16", Layout.RGB, "u2"), ("rgba16", Layout.RGBA, "u2"),
    ("bgr16", Layout.BGR, "u2"), ("bgra16", Layout.BGRA, "u2"), ("mono8", Layout.GRAY, "u1"),
    ("mono16", Layout.GRAY, "u2"), ("16UC1", Layout.DEPTH, "u2"), ("32FC1", Layout.DEPTH, "f4"),
    ("16SC1", Layout.LABEL, "i2"),
    *((f"{layout.value}{bits}", layout, f"u{bits // 8}")
      for layout in (Layout.BAYER_BGGR, Layout.BAYER_RGGB, Layout.BAYER_GBRG, Layout.BAYER_GRBG)
      for bits in (8, 16)),
)  # fmt: skip
ENCODINGS: dict[tuple[Layout, str], str] = {(layout, code): name for name, layout, code in _NAMED}
LAYOUTS: dict[str, tuple[Layout, np.dtype[Any]]] = {
    name: (layout, np.dtype(code)) for name, layout, code in _NAMED
}
_GENERIC = {"u1": "8U", "i1": "8S", "u2": "16U", "i2": "16S", "i4": "32S", "f4": "32F", "f8": "64F"}


def encoding(image: Image) -> str:
    """The ROS encoding of an image's layout and channel type; `EncodeError` when ROS has none
    (uint32 channels)."""
    code = f"{image.pixels.dtype.kind}{image.pixels.dtype.itemsize}"
    named = ENCODINGS.get((image.layout, code))
    if named is not None:
        return named
    generic = _GENERIC.get(code)
    if generic is None:
        raise EncodeError(
            IMAGE, "encoding", f"image {image.name!r}: ROS has no encoding for {image.pixels.dtype}"
        )
    return f"{generic}C{image.layout.channels}"


def image_to_cdr(image: Image, frame_id: str, stamp: tuple[int, int]) -> bytes:
    """`sensor_msgs/Image` CDR: the header, then the pixels in one copy (rows back to back).

    Raises `EncodeError` for a frame id a CDR string cannot carry, or pixels ROS has no encoding for.
    """
    rows = image.packed_rows()
    step = image.width * image.layout.channels * rows.dtype.itemsize
    pixels = rows.reshape(-1).view(np.uint8).data
    header = (stamp, frame_id)
    value = (header, image.height, image.width, encoding(image), image.big_endian, step, pixels)
    return ros_writer(IMAGE).write(value)


def compressed_image_to_cdr(image: EncodedImage, frame_id: str, stamp: tuple[int, int]) -> bytes:
    """`sensor_msgs/CompressedImage` CDR of the bytes as they came (`format` jpeg or png)."""
    return ros_writer(COMPRESSED_IMAGE).write(((stamp, frame_id), image.format, image.data))


class CameraInfoEncoder:
    """`sensor_msgs/CameraInfo` CDR for one camera and frame: the message is written once, and
    each image's stamp written into a copy of it where the writer marked it."""

    def __init__(self, intrinsics: Intrinsics, frame_id: str) -> None:
        self.intrinsics = intrinsics
        self.frame_id = frame_id
        self._template = StampedTemplate(CAMERA_INFO, _camera_info(intrinsics, frame_id, (0, 0)))

    def encode(self, stamp: tuple[int, int]) -> bytes:
        return self._template.stamped(stamp)


def camera_info_cdr(intrinsics: Intrinsics, frame_id: str, stamp: tuple[int, int]) -> bytes:
    """A `CameraInfo`: a pinhole (plumb_bob with zero distortion), K, R = I, P = [K | 0]."""
    return ros_writer(CAMERA_INFO).write(_camera_info(intrinsics, frame_id, stamp))


def _camera_info(intrinsics: Intrinsics, frame_id: str, stamp: tuple[int, int]) -> tuple[object, ...]:
    model, coefficients = NO_DISTORTION
    no_region = (0, 0, 0, 0, False)  # roi: the whole image
    return ((stamp, frame_id), intrinsics.height, intrinsics.width, model, coefficients, intrinsics.k(),
            NO_ROTATION, intrinsics.p(), 0, 0, no_region)  # fmt: skip


# --- reading (the way back to Drake) ------------------------------------------------------------------


@dataclass(frozen=True, eq=False, slots=True)
class StampedImage:
    """A ROS image: its header's frame and stamp (microseconds), and the image."""

    frame_id: str
    time_us: int
    image: Image


def image_from_cdr(data: bytes | memoryview) -> StampedImage:
    """`sensor_msgs/Image` CDR as an image named after its layout (a view of `data`: strided
    rows, either byte order).

    Raises `DecodeError` naming the field for bytes that are not an Image, an encoding with no
    Drake pixel format, a step shorter than a row, or data that is not step x height bytes.
    """
    reader = CdrReader(data, IMAGE)
    time_us, frame_id = reader.header()
    height = reader.scalar("I", "height")
    width = reader.scalar("I", "width")
    at = reader.offset
    name_of_encoding = reader.string("encoding")
    if name_of_encoding not in LAYOUTS:
        known = ", ".join(LAYOUTS)
        raise DecodeError(
            IMAGE, "encoding", at, f"{name_of_encoding!r} has no Drake pixel format (known: {known})"
        )
    layout, dtype = LAYOUTS[name_of_encoding]
    big_endian = reader.scalar("B", "is_bigendian") != 0
    step = reader.scalar("I", "step")
    at = reader.offset
    rows = reader.octets("data")
    pixel_size = layout.channels * dtype.itemsize
    if step < width * pixel_size:
        raise DecodeError(
            IMAGE, "step", at - 4, f"step {step} is shorter than a row ({width} x {pixel_size} bytes)"
        )
    if len(rows) != step * height:
        raise DecodeError(IMAGE, "data", at, f"{len(rows)} bytes are not step {step} x height {height}")
    channel = dtype.newbyteorder(">" if big_endian else "<")
    strides = (step, pixel_size, dtype.itemsize)
    pixels: Pixels = np.ndarray((height, width, layout.channels), channel, rows, 0, strides)
    return StampedImage(frame_id, time_us, Image(layout.value, time_us, layout, pixels))
