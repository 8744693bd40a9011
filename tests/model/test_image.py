"""The neutral image model: depth conventions (against Drake's own reader), channel order, files."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image as PilImage

from tests.drake_images import publish_with_drake, read_with_drake
from tests.pixels import sample_pixels
from viewer_bridge.errors import EncodeError
from viewer_bridge.model.image import Image, Layout, depth_from_rep117, depth_rep117, encode_file


def test_depth_in_metres_is_drakes_division_with_rep117_sentinels() -> None:
    millimetres = sample_pixels(np.uint16, (4, 5, 1))
    millimetres[0, 0], millimetres[0, 1] = 0, 65535
    # Compressed: Drake 1.51's reader copies only width x height bytes of uncompressed rows, so
    # half of a 16-bit image (docs/PROTOCOLS.md section 12).
    drake = read_with_drake(publish_with_drake([("depth", "depth16", millimetres)], 0.0, compress=True))
    metres = depth_rep117(Image("depth", 0, Layout.DEPTH, millimetres)).pixels
    assert metres.dtype == np.float32
    assert metres[0, 0, 0] == -np.inf and metres[0, 1, 0] == np.inf  # too close, too far (REP 117)
    # Drake reads the sentinels as plain values (0 m and 65.535 m); every other value: the same bits.
    np.testing.assert_array_equal(metres.ravel()[2:], drake["depth_image"].ravel()[2:])


def test_float_depth_maps_drakes_too_close_to_minus_infinity_and_back() -> None:
    drake = np.array([[[0.0], [np.inf], [1.5], [0.25]]], ">f4")  # big-endian on the wire
    rep117 = depth_rep117(Image("depth", 0, Layout.DEPTH, drake)).pixels
    np.testing.assert_array_equal(rep117.ravel(), [-np.inf, np.inf, 1.5, 0.25])
    ros = np.array([[[-np.inf], [np.inf], [np.nan], [0.25]]], np.float32)
    back = depth_from_rep117(Image("depth", 0, Layout.DEPTH, ros)).pixels
    np.testing.assert_array_equal(back.ravel(), [0.0, np.inf, np.inf, 0.25])  # no return: too far
    label = Image("label", 0, Layout.LABEL, np.zeros((1, 1, 1), np.int16))
    assert depth_from_rep117(label) is label


def test_channel_order_and_alpha() -> None:
    bgra = sample_pixels(np.uint8, (2, 3, 4))
    image = Image("rgb", 0, Layout.BGRA, bgra)
    rgba = image.rgb_order()
    assert rgba.layout is Layout.RGBA
    np.testing.assert_array_equal(rgba.pixels, bgra[:, :, [2, 1, 0, 3]])
    bgr = image.without_alpha()
    assert bgr.layout is Layout.BGR and np.shares_memory(bgr.pixels, bgra)
    np.testing.assert_array_equal(bgr.pixels, bgra[:, :, :3])
    depth = Image("depth", 0, Layout.DEPTH, np.zeros((1, 1, 1), np.uint16))
    assert depth.rgb_order() is depth and depth.without_alpha() is depth


@pytest.mark.parametrize(
    ("layout", "dtype", "channels"),
    [(Layout.RGBA, np.uint8, 4), (Layout.BGR, np.uint8, 3), (Layout.GRAY, np.uint8, 1),
     (Layout.DEPTH, np.uint16, 1), (Layout.DEPTH, ">u2", 1), (Layout.LABEL, np.int16, 1)],
)  # fmt: skip
def test_png_keeps_every_pixel_in_rgb_order(layout: Layout, dtype: str, channels: int) -> None:
    pixels = sample_pixels(dtype, (5, 7, channels))
    encoded = encode_file(Image("x", 3, layout, pixels), "png")
    assert (encoded.format, encoded.width, encoded.height, encoded.layout) == ("png", 7, 5, layout)
    decoded = np.asarray(PilImage.open(io.BytesIO(encoded.data))).reshape(pixels.shape)
    expected = Image("x", 3, layout, pixels).rgb_order().pixels
    np.testing.assert_array_equal(decoded.view(expected.dtype.newbyteorder("=")) if dtype != np.uint8 else decoded,
                                  expected)  # fmt: skip


def test_jpeg_leaves_alpha_out_and_float_depth_fits_no_file() -> None:
    rgba = sample_pixels(np.uint8, (8, 8, 4))
    encoded = encode_file(Image("rgb", 0, Layout.RGBA, rgba), "jpeg")
    assert PilImage.open(io.BytesIO(encoded.data)).mode == "RGB"
    with pytest.raises(EncodeError, match="png cannot hold 1 x float32"):
        encode_file(Image("depth", 0, Layout.DEPTH, np.zeros((2, 2, 1), np.float32)), "png")
    with pytest.raises(EncodeError, match="jpeg cannot hold 1 x uint16"):
        encode_file(Image("depth", 0, Layout.DEPTH, np.zeros((2, 2, 1), np.uint16)), "jpeg")
    with pytest.raises(EncodeError, match="png cannot hold an empty image"):
        encode_file(Image("rgb", 0, Layout.RGBA, np.zeros((0, 3, 4), np.uint8)), "png")


def test_a_preview_is_rgb_bytes_with_sentinels_black_and_a_colour_per_label() -> None:
    from viewer_bridge.model.image import preview

    depth = np.array([[[0], [500], [1000], [65535]]], np.uint16)
    shades = preview(Image("depth", 0, Layout.DEPTH, depth))
    assert shades.shape == (1, 4, 3) and shades.dtype == np.uint8
    assert list(shades[0, :, 0]) == [0, 255, 155, 0]  # too close and too far black, the nearest white
    labels = preview(Image("label", 0, Layout.LABEL, np.array([[[1], [2], [1]]], np.int16)))
    assert (labels[0, 0] == labels[0, 2]).all() and (labels[0, 0] != labels[0, 1]).any()
    bgra = sample_pixels(np.uint8, (2, 2, 4))
    np.testing.assert_array_equal(preview(Image("rgb", 0, Layout.BGRA, bgra)), bgra[:, :, [2, 1, 0]])
    grey = preview(Image("ir", 0, Layout.GRAY, np.array([[[0], [1000]]], np.uint16)))
    assert list(grey[0, :, 1]) == [0, 255]
