"""Drake's lcmt_image_array <-> images: against Drake's own ImageToLcmImageArrayT, Drake's lcm-gen
classes (every pixel format, channel type, byte order, row padding, compression), and the refusals."""

from __future__ import annotations

import io
import tracemalloc
import zlib
from typing import Any

import numpy as np
import pytest
from PIL import Image as PilImage

from tests.drake_images import publish_with_drake
from tests.pixels import sample_pixels
from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.image import (
    CHANNEL_DTYPES,
    LAYOUTS,
    images_to_lcm,
    read_image_array,
    unpack,
)
from viewer_bridge.lcmcodec.codecs import IMAGE_ARRAY
from viewer_bridge.model.image import Image, Layout

# Every test here builds or reads messages with Drake's own classes: a core-only run skips them all.
drake_lcmtypes = pytest.importorskip("drake")
LCMT_IMAGE = drake_lcmtypes.lcmt_image


def drake_scene_images(height: int = 6, width: int = 5) -> list[tuple[str, str, np.ndarray]]:
    """An rgb, depth and label image as ApplyCameraConfig's ports carry them."""
    return [
        ("rgb", "rgba8", sample_pixels(np.uint8, (height, width, 4))),
        ("depth", "depth16", sample_pixels(np.uint16, (height, width, 1))),
        ("label", "label16", sample_pixels(np.int16, (height, width, 1))),
    ]


@pytest.mark.parametrize("compress", [False, True])
def test_reads_what_image_to_lcm_image_array_publishes(compress: bool) -> None:
    images = drake_scene_images()
    array = read_image_array(publish_with_drake(images, 1.5, compress))
    assert array.time_us == 1_500_000 and array.frame_name == ""
    assert [packed.name for packed in array.images] == ["rgb", "depth", "label"]
    for packed, (name, _, pixels) in zip(array.images, images, strict=True):
        image = unpack(packed)
        assert (image.name, image.time_us) == (name, 1_500_000)
        np.testing.assert_array_equal(image.pixels, pixels)
    layouts = [unpack(packed).layout for packed in array.images]
    assert layouts == [Layout.RGBA, Layout.DEPTH, Layout.LABEL]


def test_writes_what_image_to_lcm_image_array_publishes() -> None:
    """Byte for byte uncompressed; compressed, the same fields and rows (zlib's bytes are its own)."""
    scene = drake_scene_images() + [
        ("grey", "grey8", sample_pixels(np.uint8, (6, 5, 1))),
        ("bgr", "bgr8", sample_pixels(np.uint8, (6, 5, 3))),
        ("far", "depth32", sample_pixels(np.float32, (6, 5, 1))),
    ]
    layouts = {"rgba8": Layout.RGBA, "depth16": Layout.DEPTH, "label16": Layout.LABEL, "grey8": Layout.GRAY,
               "bgr8": Layout.BGR, "depth32": Layout.DEPTH}  # fmt: skip
    ours = [Image(name, 2_250_000, layouts[kind], pixels) for name, kind, pixels in scene]
    assert images_to_lcm(ours, 2_250_000) == publish_with_drake(scene, 2.25, compress=False)
    theirs = drake_lcmtypes.lcmt_image_array.decode(publish_with_drake(scene, 2.25, compress=True))
    mine = drake_lcmtypes.lcmt_image_array.decode(images_to_lcm(ours, 2_250_000, compress=True))
    for expected, got in zip(theirs.images, mine.images, strict=True):
        fields = (
            "width",
            "height",
            "row_stride",
            "bigendian",
            "pixel_format",
            "channel_type",
            "compression_method",
        )
        assert [getattr(got, f) for f in fields] == [getattr(expected, f) for f in fields]
        assert got.header.frame_name == expected.header.frame_name
        assert zlib.decompress(got.data) == zlib.decompress(expected.data)


def lcm_image(name: str, pixels: np.ndarray, **fields: Any) -> Any:
    """Drake's own `lcmt_image` with the pixels' bytes as they are (any byte order, padding)."""
    image = LCMT_IMAGE()
    image.header.frame_name, image.header.utime = name, 7
    image.height, image.width = pixels.shape[:2]
    image.row_stride = pixels.shape[1] * pixels.shape[2] * pixels.dtype.itemsize
    image.data = pixels.tobytes()
    image.pixel_format, image.channel_type = LCMT_IMAGE.PIXEL_FORMAT_RGBA, LCMT_IMAGE.CHANNEL_TYPE_UINT8
    image.compression_method = LCMT_IMAGE.COMPRESSION_METHOD_NOT_COMPRESSED
    for key, value in fields.items():
        setattr(image, key, value)
    image.size = len(image.data)
    return image


def lcm_array(*images: Any) -> bytes:
    array = drake_lcmtypes.lcmt_image_array()
    array.header.utime, array.num_images, array.images = 7, len(images), list(images)
    return bytes(array.encode())


@pytest.mark.parametrize("pixel_format", sorted(LAYOUTS))
@pytest.mark.parametrize("channel_type", sorted(CHANNEL_DTYPES))
def test_every_pixel_format_and_channel_type_in_either_byte_order_with_padded_rows(
    pixel_format: int, channel_type: int
) -> None:
    layout, dtype = LAYOUTS[pixel_format], CHANNEL_DTYPES[channel_type]
    pixels = sample_pixels(dtype, (3, 4, layout.channels))
    for bigendian in (False, True):
        for padding in (0, 3):
            wire = pixels.astype(dtype.newbyteorder(">" if bigendian else "<"))
            rows = np.frombuffer(wire.tobytes(), np.uint8).reshape(3, -1)
            padded = np.concatenate((rows, np.full((3, padding), 0xEE, np.uint8)), axis=1)
            for compression in (
                LCMT_IMAGE.COMPRESSION_METHOD_NOT_COMPRESSED,
                LCMT_IMAGE.COMPRESSION_METHOD_ZLIB,
            ):
                data = padded.tobytes()
                data = zlib.compress(data) if compression == LCMT_IMAGE.COMPRESSION_METHOD_ZLIB else data
                message = lcm_image("cam", pixels, pixel_format=pixel_format, channel_type=channel_type,
                                    bigendian=bigendian, row_stride=padded.shape[1], data=data,
                                    compression_method=compression)  # fmt: skip
                image = unpack(read_image_array(lcm_array(message)).images[0])
                assert image.layout is layout and image.pixels.shape == pixels.shape
                np.testing.assert_array_equal(image.pixels, pixels)
                assert image.big_endian == (bigendian and dtype.itemsize > 1)


def file_bytes(pixels: np.ndarray, file_format: str, mode: str | None = None) -> bytes:
    out = io.BytesIO()
    squeezed = pixels[:, :, 0] if pixels.shape[2] == 1 else pixels
    if mode == "I;16":
        picture = PilImage.frombuffer(
            "I;16", squeezed.shape[::-1], squeezed.astype("<u2").tobytes(), "raw", "I;16", 0, 1
        )
    else:
        picture = PilImage.fromarray(squeezed)
    picture.save(out, file_format)
    return out.getvalue()


@pytest.mark.parametrize(
    ("pixel_format", "channel_type", "dtype", "channels", "mode"),
    [
        (LCMT_IMAGE.PIXEL_FORMAT_RGBA, LCMT_IMAGE.CHANNEL_TYPE_UINT8, np.uint8, 4, None),
        (LCMT_IMAGE.PIXEL_FORMAT_RGB, LCMT_IMAGE.CHANNEL_TYPE_UINT8, np.uint8, 3, None),
        (LCMT_IMAGE.PIXEL_FORMAT_GRAY, LCMT_IMAGE.CHANNEL_TYPE_UINT8, np.uint8, 1, None),
        (LCMT_IMAGE.PIXEL_FORMAT_DEPTH, LCMT_IMAGE.CHANNEL_TYPE_UINT16, np.uint16, 1, "I;16"),
        (LCMT_IMAGE.PIXEL_FORMAT_LABEL, LCMT_IMAGE.CHANNEL_TYPE_INT16, np.int16, 1, "I;16"),
    ],
)
def test_png_decodes_to_the_pixels_and_passes_through_as_it_came(
    pixel_format: int, channel_type: int, dtype: Any, channels: int, mode: str | None
) -> None:
    pixels = sample_pixels(dtype, (5, 7, channels))
    png = file_bytes(pixels, "PNG", mode)
    message = lcm_image("depth", pixels, pixel_format=pixel_format, channel_type=channel_type, data=png,
                        compression_method=LCMT_IMAGE.COMPRESSION_METHOD_PNG)  # fmt: skip
    packed = read_image_array(lcm_array(message)).images[0]
    np.testing.assert_array_equal(unpack(packed).pixels, pixels)
    encoded = packed.encoded()
    assert encoded is not None and encoded.format == "png" and bytes(encoded.data) == png
    assert (encoded.width, encoded.height, encoded.layout) == (7, 5, LAYOUTS[pixel_format])


def test_jpeg_decodes_as_pillow_decodes_it() -> None:
    pixels = sample_pixels(np.uint8, (16, 24, 3))
    jpeg = file_bytes(pixels, "JPEG")
    message = lcm_image("rgb", pixels, pixel_format=LCMT_IMAGE.PIXEL_FORMAT_RGB, data=jpeg,
                        compression_method=LCMT_IMAGE.COMPRESSION_METHOD_JPEG)  # fmt: skip
    packed = read_image_array(lcm_array(message)).images[0]
    np.testing.assert_array_equal(unpack(packed).pixels, np.asarray(PilImage.open(io.BytesIO(jpeg))))
    assert packed.encoded() is not None and packed.encoded().format == "jpeg"  # type: ignore[union-attr]
    assert read_image_array(lcm_array(lcm_image("rgb", pixels))).images[0].encoded() is None


RGBA = sample_pixels(np.uint8, (4, 6, 4))
DEPTH = sample_pixels(np.uint16, (4, 6, 1))
ZLIB = LCMT_IMAGE.COMPRESSION_METHOD_ZLIB
PNG = LCMT_IMAGE.COMPRESSION_METHOD_PNG


def depth_image(**fields: Any) -> Any:
    depth = {"pixel_format": LCMT_IMAGE.PIXEL_FORMAT_DEPTH, "channel_type": LCMT_IMAGE.CHANNEL_TYPE_UINT16}
    return lcm_image("depth", DEPTH, **{**depth, **fields})


BAD_DEPTH = {
    "unknown pixel format": (dict(pixel_format=42), "pixel_format", "unknown pixel_format 42"),
    "unknown channel type": (dict(channel_type=9), "channel_type", "unknown channel_type 9"),
    "unknown compression": (dict(compression_method=7), "compression_method", "unknown compression_method 7"),
    "negative width": (dict(width=-1), "width", "negative size"),
    "stride shorter than a row": (dict(row_stride=11), "row_stride", "row_stride 11 is shorter than a row"),
    "size is not stride x height": (dict(data=DEPTH.tobytes()[:-2]), "size", "46 bytes are not row_stride 12"),
    "zlib stream too long": (dict(data=zlib.compress(DEPTH.tobytes() + b"x"), compression_method=ZLIB), "data",
                             "zlib data expands past 48 bytes"),
    "zlib stream too short": (dict(data=zlib.compress(DEPTH.tobytes()[:-2]), compression_method=ZLIB), "size",
                              "46 bytes are not"),
    "zlib stream cut": (dict(data=zlib.compress(DEPTH.tobytes())[:-3], compression_method=ZLIB), "data",
                        "ends early"),
    "not zlib": (dict(data=b"not zlib at all", compression_method=ZLIB), "data", "not a zlib stream"),
    "bytes after the stream": (dict(data=zlib.compress(DEPTH.tobytes()) + b"!!", compression_method=ZLIB), "data",
                               "2 bytes after the zlib stream"),
    "png of another size": (dict(data=file_bytes(DEPTH[:2], "PNG", "I;16"), compression_method=PNG), "data",
                            "PNG is 6 x 2, the header says 6 x 4"),
    "png of other channels": (dict(data=file_bytes(RGBA, "PNG"), compression_method=PNG), "data",
                              "PNG decodes to 4 channel(s) of uint8"),
    "not a png": (dict(data=b"\x89PNG nothing" * 10, compression_method=PNG), "data", "not a valid PNG"),
    "png too small for its pixels": (dict(data=b"\x89PNG", width=2000, height=2000, row_stride=4000,
                                          compression_method=PNG), "size", "4 bytes of PNG cannot hold 8000000 bytes"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD_DEPTH))
def test_a_bad_image_is_a_decode_error_naming_it_and_the_field_and_the_others_still_decode(case: str) -> None:
    fields, field, reason = BAD_DEPTH[case]
    data = lcm_array(lcm_image("rgb", RGBA), depth_image(**fields))
    array = read_image_array(data)
    with pytest.raises(DecodeError) as raised:
        unpack(array.images[1])
    error = raised.value
    assert error.type_name == "drake.lcmt_image_array" and error.field == f"images[1].{field}"
    assert "image 'depth'" in str(error) and reason in str(error), str(error)
    np.testing.assert_array_equal(unpack(array.images[0]).pixels, RGBA)


def test_a_zlib_bomb_is_refused_without_being_expanded() -> None:
    """64 MiB of zeros compress to 64 KiB; the header declares 48 bytes."""
    bomb = zlib.compress(bytes(64 << 20), 9)
    packed = read_image_array(lcm_array(depth_image(data=bomb, compression_method=ZLIB))).images[0]
    tracemalloc.start()
    try:
        with pytest.raises(DecodeError, match="zlib data expands past 48 bytes"):
            unpack(packed)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20


def test_the_fast_reader_agrees_with_the_schema_codec_and_refuses_every_truncation() -> None:
    data = lcm_array(
        lcm_image("rgb", RGBA), depth_image(data=zlib.compress(DEPTH.tobytes()), compression_method=ZLIB)
    )
    array, message = read_image_array(data), IMAGE_ARRAY.decode(data)
    assert array.time_us == message.header.utime and len(array.images) == message.num_images
    for packed, image in zip(array.images, message.images, strict=True):
        assert (packed.name, packed.time_us) == (image.header.frame_name, image.header.utime)
        assert (packed.width, packed.height, packed.row_stride) == (
            image.width,
            image.height,
            image.row_stride,
        )
        assert bytes(packed.data) == image.data and packed.bigendian == image.bigendian
        assert (packed.pixel_format, packed.channel_type, packed.compression) == (
            image.pixel_format,
            image.channel_type,
            image.compression_method,
        )
    for end in range(len(data)):
        with pytest.raises(DecodeError):
            read_image_array(data[:end])
    with pytest.raises(DecodeError, match="1 trailing bytes"):
        read_image_array(data + b"\0")
    with pytest.raises(DecodeError, match="is not drake.lcmt_image_array's"):
        read_image_array(b"\0" * 8 + data[8:])
