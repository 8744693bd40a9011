"""Neutral images (`viewer_bridge.model.image`) as Foxglove's `RawImage`, `CompressedImage` and `CameraCalibration`.

`RawImage` is written by hand on the protobuf wire, so that the rows are copied once (the head,
then the rows, then the frame id: field order, as protobuf writes it). It has no byte-order flag:
big-endian pixels are swapped to little-endian. Its encodings are ROS's
(`viewer_bridge.formats.ros.image.encoding`); Foxglove's Image panel has no 16SC1, so labels go as
16UC1 (Drake's labels are never negative: the same bits). The other two are small and made with
foxglove-schemas-protobuf's classes.
"""

from __future__ import annotations

import struct

import numpy as np

from viewer_bridge.formats.protowire import key, length_delimited, varint, varint_field
from viewer_bridge.formats.ros.image import encoding
from viewer_bridge.model.image import NO_DISTORTION, NO_ROTATION, EncodedImage, Image, Intrinsics

_FIXED32 = struct.Struct("<I")
_PANEL_ENCODINGS = {"16SC1": "16UC1"}  # what the Image panel draws, for what it does not


def timestamp(stamp: tuple[int, int]) -> bytes:
    """A `google.protobuf.Timestamp` body (seconds, nanos; zeros left out, as protobuf does)."""
    return varint_field(1, stamp[0]) + varint_field(2, stamp[1])


def raw_image(image: Image, frame_id: str, stamp: tuple[int, int]) -> bytes:
    """`foxglove.RawImage` bytes: the pixels little-endian, rows back to back, in one copy."""
    rows = image.packed_rows()
    if image.big_endian:
        rows = rows.astype(rows.dtype.newbyteorder("<"))
    name = encoding(image)
    head = b"".join((
        length_delimited(1, timestamp(stamp)),
        key(2, 5), _FIXED32.pack(image.width),
        key(3, 5), _FIXED32.pack(image.height),
        length_delimited(4, _PANEL_ENCODINGS.get(name, name).encode()),
        key(5, 5), _FIXED32.pack(image.width * image.layout.channels * rows.dtype.itemsize),
        key(6, 2), varint(rows.nbytes),
    ))  # fmt: skip
    return b"".join((head, rows.reshape(-1).view(np.uint8).data, length_delimited(7, frame_id.encode())))


def compressed_image(image: EncodedImage, frame_id: str, stamp: tuple[int, int]) -> bytes:
    """`foxglove.CompressedImage` of the bytes as they came (`format` jpeg or png)."""
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage  # the foxglove extra's

    message = CompressedImage(frame_id=frame_id, data=bytes(image.data), format=image.format)
    message.timestamp.seconds, message.timestamp.nanos = stamp
    return message.SerializeToString()


def camera_calibration(intrinsics: Intrinsics, frame_id: str, stamp: tuple[int, int]) -> bytes:
    """`foxglove.CameraCalibration`: a pinhole without distortion, as the ROS CameraInfo."""
    from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration  # the foxglove extra's

    model, coefficients = NO_DISTORTION
    message = CameraCalibration(frame_id=frame_id, width=intrinsics.width, height=intrinsics.height,
                                distortion_model=model, D=coefficients, K=intrinsics.k(), R=NO_ROTATION,
                                P=intrinsics.p())  # fmt: skip
    message.timestamp.seconds, message.timestamp.nanos = stamp
    return message.SerializeToString()
