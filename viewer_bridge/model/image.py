"""Camera images as neutral types: pixels as a numpy view, what their channels mean, when they were taken.

`viewer_bridge.formats.drake.image` reads Drake's `lcmt_image_array` into these and writes them back;
`viewer_bridge.formats.ros.image` (sensor_msgs) and `viewer_bridge.formats.foxglove.image` write them, and read
them for the way back. An `Image` holds its pixels as a height x width x channels array in any
byte order, its rows possibly strided (a view of the bytes that came, never a copy made to
normalise them); an `EncodedImage` is one still in JPEG or PNG, passed on without decoding.

Depth follows Drake's conventions (docs/PROTOCOLS.md section 12): uint16 in millimetres with 0
for too close and 65535 for too far, or float32 in metres with 0 for too close and +inf for too
far. ROS's REP 117 wants float metres with -inf for too close, +inf for too far and NaN for no
return: `depth_rep117` and `depth_from_rep117` convert between the two, here and nowhere else.
"""

from __future__ import annotations

import enum
import io
import math
import sys
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from PIL import Image as PilImage

from viewer_bridge.errors import EncodeError

Pixels = npt.NDArray[Any]  # height x width x channels, any dtype and byte order
FileFormat = Literal["jpeg", "png"]

DEPTH_16U_TOO_CLOSE = 0  # Drake's Depth16U sentinels, in millimetres
DEPTH_16U_TOO_FAR = 65535
DEPTH_32F_TOO_CLOSE = 0.0  # Drake's Depth32F: too far is +inf
MILLIMETRES_PER_METRE = 1e3


class Layout(enum.Enum):
    """What an image's channels mean: Drake's `pixel_format`s."""

    GRAY = "gray"
    RGB = "rgb"
    BGR = "bgr"
    RGBA = "rgba"
    BGRA = "bgra"
    DEPTH = "depth"
    LABEL = "label"
    MASK = "mask"
    DISPARITY = "disparity"
    BAYER_BGGR = "bayer_bggr"
    BAYER_RGGB = "bayer_rggb"
    BAYER_GBRG = "bayer_gbrg"
    BAYER_GRBG = "bayer_grbg"

    @property
    def channels(self) -> int:
        return _CHANNELS.get(self, 1)

    def without_alpha(self) -> Layout | None:
        """The layout without its alpha channel (RGBA -> RGB), or None when it has none."""
        return _WITHOUT_ALPHA.get(self)


_CHANNELS = {Layout.RGB: 3, Layout.BGR: 3, Layout.RGBA: 4, Layout.BGRA: 4}
_WITHOUT_ALPHA = {Layout.RGBA: Layout.RGB, Layout.BGRA: Layout.BGR}
_RGB_ORDER = {Layout.BGR: Layout.RGB, Layout.BGRA: Layout.RGBA}


@dataclass(frozen=True, eq=False, slots=True)
class Image:
    """One image: `name` says which of a camera's images it is (Drake's port name: rgb, depth,
    label), `time_us` when it was taken (Drake's sim time), `pixels` height x width x channels."""

    name: str
    time_us: int
    layout: Layout
    pixels: Pixels

    @property
    def height(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def width(self) -> int:
        return int(self.pixels.shape[1])

    @property
    def big_endian(self) -> bool:
        order = self.pixels.dtype.byteorder
        return order == ">" or (order == "=" and sys.byteorder == "big")

    def packed_rows(self) -> Pixels:
        """The pixels with rows back to back (what a format without a row step needs): the same
        array when they already are, else a copy."""
        return np.ascontiguousarray(self.pixels)

    def rgb_order(self) -> Image:
        """BGR as RGB, BGRA as RGBA (the channels reordered: a copy); any other image as it is.
        For readers that know RGB only: PNG, JPEG, and Drake's `LcmImageArrayToImages`."""
        layout = _RGB_ORDER.get(self.layout)
        if layout is None:
            return self
        order = [2, 1, 0, 3][: self.layout.channels]
        return replace(self, layout=layout, pixels=self.pixels[:, :, order])

    def without_alpha(self) -> Image:
        """RGBA as RGB, BGRA as BGR (a strided view); any other image as it is."""
        layout = self.layout.without_alpha()
        return self if layout is None else replace(self, layout=layout, pixels=self.pixels[:, :, :3])


@dataclass(frozen=True, eq=False, slots=True)
class EncodedImage:
    """An image still in a file format, as it came: passed on without decoding."""

    name: str
    time_us: int
    layout: Layout
    width: int
    height: int
    format: FileFormat
    data: bytes | memoryview


@dataclass(frozen=True, slots=True)
class Intrinsics:
    """A pinhole camera's intrinsics in pixels, with the first pixel's centre at (0, 0) (Drake's
    `CameraInfo` and ROS's `CameraInfo` agree on that): no distortion."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_fov(
        cls, width: int, height: int, fov_y_deg: float | None, fov_x_deg: float | None = None
    ) -> Intrinsics:
        """As Drake's `CameraConfig.focal` (`FovDegrees`) makes them: a field of view sets the
        focal length along its axis, the other axis takes the same (square pixels) unless given
        too; the principal point is the image's centre, (width / 2 - 0.5, height / 2 - 0.5)."""
        fy = height / 2 / math.tan(math.radians(fov_y_deg) / 2) if fov_y_deg is not None else None
        fx = width / 2 / math.tan(math.radians(fov_x_deg) / 2) if fov_x_deg is not None else None
        if fx is None and fy is None:
            raise ValueError("a field of view is needed, vertical or horizontal")
        fx = fy if fx is None else fx
        fy = fx if fy is None else fy
        assert fx is not None and fy is not None
        return cls(width, height, fx, fy, width / 2 - 0.5, height / 2 - 0.5)

    def k(self) -> list[float]:
        """The camera matrix K, row by row (3 x 3)."""
        return [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]

    def p(self) -> list[float]:
        """The projection matrix P = [K | 0] of a camera that is not rectified (3 x 4)."""
        return [self.fx, 0.0, self.cx, 0.0, 0.0, self.fy, self.cy, 0.0, 0.0, 0.0, 1.0, 0.0]


# What ROS's CameraInfo and Foxglove's CameraCalibration say of a camera without distortion.
NO_DISTORTION = ("plumb_bob", [0.0] * 5)
NO_ROTATION = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]  # R: no rectification


JPEG_QUALITY = 90


def encode_file(image: Image, file_format: FileFormat) -> EncodedImage:
    """The image as a PNG (lossless: 8-bit grey, RGB, RGBA; 16-bit grey, int16 labels as their
    bits) or a JPEG (8-bit grey or colour, alpha left out), colours in RGB order as both formats
    keep them. Raises `EncodeError` for an image the format cannot hold (float depth, no pixels)."""
    pixels = image.rgb_order().pixels
    channels = pixels.shape[2]
    if file_format == "jpeg" and channels == 4:
        pixels, channels = pixels[:, :, :3], 3
    one_byte = pixels.dtype.itemsize == 1 and pixels.dtype.kind == "u"
    two_bytes = (
        pixels.dtype.itemsize == 2 and pixels.dtype.kind in "iu" and channels == 1 and file_format == "png"
    )
    if not image.width or not image.height:  # found by bench/fuzz.py: Pillow cannot write one
        raise EncodeError(
            "image", "pixels", f"image {image.name!r}: {file_format} cannot hold an empty image"
        )
    if not (one_byte and channels in (1, 3, 4) or two_bytes):
        raise EncodeError(
            "image", "pixels", f"image {image.name!r}: {file_format} cannot hold {channels} x {pixels.dtype}"
        )
    rows = np.ascontiguousarray(pixels.astype(pixels.dtype.newbyteorder("<"), copy=False))
    size = (image.width, image.height)
    if two_bytes:  # int16 labels too: PNG keeps the 16 bits, a reader takes them back as int16
        picture = PilImage.frombuffer("I;16", size, rows.tobytes(), "raw", "I;16", 0, 1)
    else:
        picture = PilImage.fromarray(rows[:, :, 0] if channels == 1 else rows)
    out = io.BytesIO()
    if file_format == "png":
        picture.save(out, "PNG", compress_level=1)
    else:
        picture.save(out, "JPEG", quality=JPEG_QUALITY)
    return EncodedImage(
        image.name, image.time_us, image.layout, image.width, image.height, file_format, out.getvalue()
    )


def preview(image: Image) -> npt.NDArray[np.uint8]:
    """The image as height x width x 3 RGB bytes for a person to look at: colour as it is; depth
    as grey, the nearest white and the farthest dark, too close and too far black; labels a
    colour each (the same label, the same colour, in every picture)."""
    pixels = image.rgb_order().pixels
    if image.layout is Layout.DEPTH:
        metres = depth_rep117(image).pixels[:, :, 0]
        seen = np.isfinite(metres)
        # By rank among the distances seen (histogram equalisation): every step of depth shows.
        distances = np.sort(metres[seen])
        rank = np.searchsorted(distances, np.where(seen, metres, 0.0)) / max(len(distances), 1)
        shade = np.where(seen, 255 - 200 * rank, 0.0)
        return np.repeat(shade[:, :, None], 3, axis=2).astype(np.uint8)
    if image.layout is Layout.LABEL:
        # Hues a golden angle apart: neighbouring labels far apart on the colour wheel.
        hue = (pixels[:, :, 0].astype(np.float64) * 0.618034) % 1.0
        sector = hue * 6
        ramp = np.clip(np.abs((sector[:, :, None] - np.array([3, 1, 5])) % 6 - 3) - 1, 0, 1)  # hue -> RGB
        colours: npt.NDArray[np.uint8] = (40 + 200 * ramp).astype(np.uint8)
        return colours
    if pixels.dtype != np.uint8:  # 16-bit or float colour, grey: scaled to their range
        values = pixels.astype(np.float64)
        low, high = float(values.min(initial=0)), float(values.max(initial=1))
        pixels = (255 * (values - low) / max(high - low, 1e-9)).astype(np.uint8)
    rgb: npt.NDArray[np.uint8] = np.ascontiguousarray(
        np.broadcast_to(pixels[:, :, :3], (*pixels.shape[:2], 3))
    )
    return rgb


def depth_rep117(image: Image) -> Image:
    """A DEPTH image in float32 metres with REP 117's sentinels: too close -inf, too far +inf.

    From Drake's uint16 millimetres each value is divided as Drake's `LcmImageArrayToImages`
    divides it (float to double, / 1e3, rounded to float), so the metres are the same bits.
    """
    pixels = image.pixels
    if pixels.dtype.kind == "u":
        metres = (pixels.astype(np.float64) / MILLIMETRES_PER_METRE).astype(np.float32)
        metres[pixels == DEPTH_16U_TOO_CLOSE] = -np.inf
        metres[pixels == DEPTH_16U_TOO_FAR] = np.inf
    else:
        metres = pixels.astype(np.float32)  # a copy in native order: the sentinel is written below
        metres[pixels == DEPTH_32F_TOO_CLOSE] = -np.inf
    return replace(image, pixels=metres)


def depth_from_rep117(image: Image) -> Image:
    """A float DEPTH image with REP 117's sentinels in Drake's Depth32F conventions: -inf (too
    close) becomes 0, NaN (no return: nothing within range, as Drake's renderers report the
    background) becomes +inf. Other images are returned as they are."""
    pixels = image.pixels
    if image.layout is not Layout.DEPTH or pixels.dtype.kind != "f":
        return image
    metres = pixels.astype(np.float32)
    metres[np.isneginf(metres)] = DEPTH_32F_TOO_CLOSE
    metres[np.isnan(metres)] = np.inf
    return replace(image, pixels=metres)
