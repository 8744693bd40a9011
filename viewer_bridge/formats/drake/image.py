"""Drake's `lcmt_image_array` <-> neutral images (`viewer_bridge.model.image`), docs/PROTOCOLS.md section 12.

Reading is two steps, so that a route that only passes JPEG or PNG bytes on never decodes them
and a lazy route with no subscriber pays only for the first: `read_image_array` walks the
message and keeps each image's header fields and a view of its bytes (`PackedImage`, no copy);
`unpack` turns one into pixels. Every `pixel_format`, `channel_type`, `row_stride` (padding is
kept as a strided view) and `bigendian` is read; compression none, zlib (Drake's default, level 1
as `ImageToLcmImageArrayT` writes it), JPEG and PNG (Pillow). A zlib stream
(`viewer_bridge.formats.drake.inflate`) is never expanded past the size the header declares
(row_stride x height): a bomb is refused, not inflated.
Every mismatch is a `DecodeError` for `drake.lcmt_image_array` naming the image's index and
field, its reason naming the image (`image 'depth': ...`).

Writing (`images_to_lcm`) lays an image out as `ImageToLcmImageArrayT` does: rows back to back,
little-endian, the port name as the image's `frame_name`, zlib level 1 when asked to compress.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from PIL import Image as PilImage

from viewer_bridge.errors import DecodeError, EncodeError, InflateError
from viewer_bridge.formats.drake.inflate import inflate
from viewer_bridge.lcmcodec.codecs import HEADER, IMAGE, IMAGE_ARRAY
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.model.image import EncodedImage, FileFormat, Image, Layout, Pixels

TYPE_NAME = IMAGE_ARRAY.type_name
NOT_COMPRESSED = int(IMAGE.constant("COMPRESSION_METHOD_NOT_COMPRESSED"))
ZLIB = int(IMAGE.constant("COMPRESSION_METHOD_ZLIB"))
JPEG = int(IMAGE.constant("COMPRESSION_METHOD_JPEG"))
PNG = int(IMAGE.constant("COMPRESSION_METHOD_PNG"))
ZLIB_LEVEL = 1  # ImageToLcmImageArrayT's Z_BEST_SPEED

# pixel_format -> layout, by the schema's constant names (PIXEL_FORMAT_RGB -> Layout.RGB).
LAYOUTS: dict[int, Layout] = {int(IMAGE.constant(f"PIXEL_FORMAT_{layout.name}")): layout for layout in Layout}
PIXEL_FORMATS = {layout: value for value, layout in LAYOUTS.items()}
# channel_type -> numpy's type of one channel (little-endian; a big-endian image swaps it).
CHANNEL_DTYPES: dict[int, np.dtype[Any]] = {
    int(IMAGE.constant(f"CHANNEL_TYPE_{name}")): np.dtype(code)
    for name, code in (("INT8", "i1"), ("UINT8", "u1"), ("INT16", "<i2"), ("UINT16", "<u2"),
                       ("INT32", "<i4"), ("UINT32", "<u4"), ("FLOAT32", "<f4"), ("FLOAT64", "<f8"))
}  # fmt: skip
CHANNEL_TYPES = {dtype: value for value, dtype in CHANNEL_DTYPES.items()}
_FILE_FORMATS: dict[int, FileFormat] = {JPEG: "jpeg", PNG: "png"}
_COMPRESSIONS = (NOT_COMPRESSED, ZLIB, JPEG, PNG)
# Deflate cannot shrink data more than 1032:1 (PNG adds a filter byte per row) and JPEG less: a
# JPEG or PNG declaring more pixels than this many times its size is refused before Pillow
# allocates them.
MAX_COMPRESSION_RATIO = 1100


@dataclass(frozen=True, slots=True)
class PackedImage:
    """One `lcmt_image` as it came: its header fields and a view of its bytes, not yet unpacked."""

    index: int  # in the array
    offset: int  # of the image in the message (where its errors point)
    name: str  # header.frame_name: ImageToLcmImageArrayT's port name (rgb, depth, label)
    time_us: int
    width: int
    height: int
    row_stride: int
    data: memoryview
    data_offset: int
    bigendian: bool
    pixel_format: int
    channel_type: int
    compression: int

    def error(self, field: str, reason: str, offset: int | None = None) -> DecodeError:
        where = self.offset if offset is None else offset
        return DecodeError(
            TYPE_NAME, f"images[{self.index}].{field}", where, f"image {self.name!r}: {reason}"
        )

    def layout(self) -> Layout:
        layout = LAYOUTS.get(self.pixel_format)
        if layout is None:
            raise self.error("pixel_format", f"unknown pixel_format {self.pixel_format}")
        return layout

    def dtype(self) -> np.dtype[Any]:
        dtype = CHANNEL_DTYPES.get(self.channel_type)
        if dtype is None:
            raise self.error("channel_type", f"unknown channel_type {self.channel_type}")
        return dtype.newbyteorder(">") if self.bigendian else dtype

    def encoded(self) -> EncodedImage | None:
        """The JPEG or PNG bytes as they came (for a pass-through), or None for other compressions."""
        file_format = _FILE_FORMATS.get(self.compression)
        if file_format is None:
            return None
        return EncodedImage(
            self.name, self.time_us, self.layout(), self.width, self.height, file_format, self.data
        )


@dataclass(frozen=True, slots=True)
class ImageArray:
    """An `lcmt_image_array`: its header's time and frame name, and its images still packed."""

    time_us: int
    frame_name: str
    images: tuple[PackedImage, ...]


# --- reading --------------------------------------------------------------------------------------------


def read_image_array(data: Buffer) -> ImageArray:
    """The array's header and a `PackedImage` per image, views into `data` (nothing is copied).

    Raises `DecodeError` for bytes that are not an `lcmt_image_array` (wrong fingerprint,
    truncated, a negative count or size, trailing bytes).
    """
    reader = _Reader(data)
    reader.fingerprint()
    _, time_us, frame_name = reader.header("header")
    count = reader.i32("num_images")
    # The smallest image: a header with an empty name (4 + 8 + 5) and 4 x int32, 4 x int8.
    if count < 0 or count * 37 > reader.left():
        raise DecodeError(
            TYPE_NAME, "num_images", reader.offset - 4, f"count {count} does not fit the bytes left"
        )
    images = tuple(reader.image(index) for index in range(count))
    if reader.left():
        raise DecodeError(TYPE_NAME, "<end>", reader.offset, f"{reader.left()} trailing bytes")
    return ImageArray(time_us, frame_name, images)


class _Reader:
    """Big-endian LCM fields from a buffer, every read checked against the bytes left."""

    _HEADER = struct.Struct(">iq")
    _I32 = struct.Struct(">i")
    _IMAGE_SIZES = struct.Struct(">iiii")  # width, height, row_stride, size
    _IMAGE_TAIL = struct.Struct(">bbbb")  # bigendian, pixel_format, channel_type, compression_method

    def __init__(self, data: Buffer) -> None:
        self.buffer = memoryview(data).cast("B")
        self.offset = 0

    def left(self) -> int:
        return len(self.buffer) - self.offset

    def take(self, size: int, field: str) -> int:
        start = self.offset
        if size > len(self.buffer) - start:
            raise DecodeError(TYPE_NAME, field, start, f"truncated: needs {size} bytes, {self.left()} remain")
        self.offset = start + size
        return start

    def fingerprint(self) -> None:
        start = self.take(8, "<fingerprint>")
        if self.buffer[start : start + 8] != IMAGE_ARRAY.packed_fingerprint:
            found = bytes(self.buffer[start : start + 8]).hex()
            raise DecodeError(TYPE_NAME, "<fingerprint>", 0, f"fingerprint {found} is not {TYPE_NAME}'s")

    def i32(self, field: str) -> int:
        value: int = self._I32.unpack_from(self.buffer, self.take(4, field))[0]
        return value

    def string(self, field: str) -> str:
        length = self.i32(field)
        if length <= 0:
            raise DecodeError(
                TYPE_NAME, field, self.offset - 4, f"string length {length} leaves no room for its NUL"
            )
        start = self.take(length, field)
        if self.buffer[start + length - 1] != 0:
            raise DecodeError(TYPE_NAME, field, start + length - 1, "string is not NUL-terminated")
        try:
            return str(self.buffer[start : start + length - 1], "utf-8")
        except UnicodeDecodeError as error:
            raise DecodeError(TYPE_NAME, field, start + error.start, "invalid UTF-8") from None

    def header(self, field: str) -> tuple[int, int, str]:
        """An `lcmt_header`: seq, utime, frame_name."""
        seq, utime = self._HEADER.unpack_from(self.buffer, self.take(self._HEADER.size, f"{field}.utime"))
        return seq, utime, self.string(f"{field}.frame_name")

    def image(self, index: int) -> PackedImage:
        field = f"images[{index}]"
        offset = self.offset
        _, time_us, name = self.header(f"{field}.header")
        sizes = self.take(self._IMAGE_SIZES.size, f"{field}.size")
        width, height, row_stride, size = self._IMAGE_SIZES.unpack_from(self.buffer, sizes)
        if size < 0:
            raise DecodeError(TYPE_NAME, f"{field}.size", sizes + 12, f"image {name!r}: negative size {size}")
        start = self.take(size, f"{field}.data")
        tail = self.take(self._IMAGE_TAIL.size, f"{field}.compression_method")
        bigendian, pixel_format, channel_type, compression = self._IMAGE_TAIL.unpack_from(self.buffer, tail)
        return PackedImage(index, offset, name, time_us, width, height, row_stride,
                           self.buffer[start : start + size], start, bool(bigendian), pixel_format,
                           channel_type, compression)  # fmt: skip


def unpack(packed: PackedImage) -> Image:
    """The image's pixels: height x width x channels, a view of the message's bytes when they
    came uncompressed (strided past any row padding), else of what they decompress to.

    Raises `DecodeError` naming the image and field for an unknown enum, a negative size, a row
    stride shorter than a row, data that is not row_stride x height bytes (before compression or
    after), a zlib stream that would expand past that, or JPEG/PNG bytes that do not decode to
    the declared size, channels and channel type.
    """
    layout, dtype = packed.layout(), packed.dtype()
    if packed.compression not in _COMPRESSIONS:
        raise packed.error("compression_method", f"unknown compression_method {packed.compression}")
    if packed.width < 0 or packed.height < 0:
        raise packed.error("width", f"negative size {packed.width} x {packed.height}")
    pixel_size = layout.channels * dtype.itemsize
    if packed.row_stride < packed.width * pixel_size:
        raise packed.error(
            "row_stride",
            f"row_stride {packed.row_stride} is shorter than a row ({packed.width} pixels of {pixel_size} bytes)",
        )
    if packed.compression in _FILE_FORMATS:
        return Image(packed.name, packed.time_us, layout, _decode_file(packed, layout, dtype))
    expected = packed.row_stride * packed.height
    rows: Buffer | npt.NDArray[np.uint8] = packed.data
    if packed.compression == ZLIB:
        try:
            rows = inflate(packed.data, expected)
        except InflateError as error:
            raise packed.error(
                "data", f"{error} (row_stride x height = {expected})", packed.data_offset
            ) from None
    if len(rows) != expected:
        raise packed.error(
            "size",
            f"{len(rows)} bytes are not row_stride {packed.row_stride} x height {packed.height} = {expected}",
            packed.data_offset,
        )
    shape = (packed.height, packed.width, layout.channels)
    strides = (packed.row_stride, pixel_size, dtype.itemsize)
    pixels: Pixels = np.ndarray(shape, dtype, rows, 0, strides)
    return Image(packed.name, packed.time_us, layout, pixels)


def _decode_file(packed: PackedImage, layout: Layout, dtype: np.dtype[Any]) -> Pixels:
    """JPEG or PNG bytes decoded by Pillow, checked against what the header declares (`bigendian`
    means nothing here: the decoder gives native order, as Drake's does)."""
    what = _FILE_FORMATS[packed.compression].upper()
    declared = packed.width * packed.height * layout.channels * dtype.itemsize
    if declared > MAX_COMPRESSION_RATIO * len(packed.data):
        raise packed.error(
            "size",
            f"{len(packed.data)} bytes of {what} cannot hold {declared} bytes of pixels",
            packed.data_offset,
        )
    try:
        with PilImage.open(io.BytesIO(packed.data), formats=[what]) as picture:
            if picture.size != (packed.width, packed.height):  # from the file's header: nothing decoded yet
                width, height = picture.size
                raise packed.error(
                    "data", f"{what} is {width} x {height}, the header says {packed.width} x {packed.height}"
                )
            decoded = np.asarray(picture)
    except (OSError, SyntaxError, ValueError, PilImage.DecompressionBombError) as error:
        raise packed.error("data", f"not a valid {what}: {error}", packed.data_offset) from None
    decoded = decoded.reshape(packed.height, packed.width, -1)
    decoded = decoded.astype(decoded.dtype.newbyteorder("="), copy=False)
    wanted = dtype.newbyteorder("=")
    # PNG has no signed 16-bit samples: a label image's int16 come as uint16 bits, read as they are.
    same_bits = (
        decoded.dtype.kind in "iu" and wanted.kind in "iu" and decoded.dtype.itemsize == wanted.itemsize
    )
    if decoded.shape[2] != layout.channels or not same_bits and decoded.dtype != wanted:
        raise packed.error(
            "data",
            f"{what} decodes to {decoded.shape[2]} channel(s) of {decoded.dtype}, the header says "
            f"{layout.channels} of {wanted} ({layout.name})",
            packed.data_offset,
        )
    return decoded.view(wanted) if same_bits else decoded


# --- writing --------------------------------------------------------------------------------------------


def images_to_lcm(
    images: Sequence[Image], time_us: int, compress: bool = False, frame_name: str = ""
) -> bytes:
    """Images as an encoded `lcmt_image_array`, laid out as `ImageToLcmImageArrayT` lays it out:
    rows back to back, little-endian, zlib level 1 when `compress`; each image's `frame_name` is
    its name, the array's is `frame_name` (Drake leaves it empty).

    Raises `EncodeError` for a channel type `lcmt_image` has no value for.
    """
    message = IMAGE_ARRAY.message_class(
        header=HEADER.message_class(seq=0, utime=int(time_us), frame_name=frame_name),
        num_images=len(images),
        images=[_lcm_image(image, compress) for image in images],
    )
    return IMAGE_ARRAY.encode(message)


def _lcm_image(image: Image, compress: bool) -> Any:
    dtype = image.pixels.dtype.newbyteorder("<") if image.pixels.dtype.itemsize > 1 else image.pixels.dtype
    channel_type = CHANNEL_TYPES.get(dtype)
    if channel_type is None:
        raise EncodeError(
            TYPE_NAME, "images.channel_type", f"image {image.name!r}: no channel type for {dtype}"
        )
    pixels = np.ascontiguousarray(image.pixels, dtype=dtype)
    rows = zlib.compress(pixels.data, ZLIB_LEVEL) if compress else pixels.tobytes()
    return IMAGE.message_class(
        header=HEADER.message_class(seq=0, utime=int(image.time_us), frame_name=image.name),
        width=image.width,
        height=image.height,
        row_stride=image.width * image.layout.channels * dtype.itemsize,
        size=len(rows),
        data=rows,
        bigendian=False,
        pixel_format=PIXEL_FORMATS[image.layout],
        channel_type=channel_type,
        compression_method=ZLIB if compress else NOT_COMPRESSED,
    )
