"""Drake's `lcmt_point_cloud` <-> the neutral `StampedPointCloud`.

What Drake's `PointCloudToLcm` publishes (and meldis reads): x, y, z FLOAT32 at 0, 4, 8, `rgb`
UINT32 at 12 holding the bytes r, g, b, 0, then normal_x/y/z, one row (`height` 1), the
IS_STRICTLY_FINITE flag, and filler bytes that align the point data to 16 bytes in the encoded
message. `cloud_to_lcm` writes exactly that, so meldis shows what the bridge sends.
"""

from __future__ import annotations

from viewer_bridge.formats.point_fields import (
    DRAKE_RGB,
    UINT32,
    Layout,
    PointField,
    read_points,
    write_points,
)
from viewer_bridge.lcmcodec.codecs import POINT_CLOUD, POINT_CLOUD_FIELD
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.model.scene import StampedPointCloud, frame_name

TYPE_NAME = POINT_CLOUD.type_name
IS_BIGENDIAN = int(POINT_CLOUD.constant("IS_BIGENDIAN"))
IS_STRICTLY_FINITE = int(POINT_CLOUD.constant("IS_STRICTLY_FINITE"))
_DATA_ALIGNMENT = 16  # PointCloudToLcm's filler makes the encoded size before `data` a multiple of this


def cloud_from_lcm(data: Buffer) -> StampedPointCloud:
    """An encoded `lcmt_point_cloud` as a stamped cloud (frame `::` turned into `/`).

    Raises `DecodeError` naming the field for bytes that are not one, for sizes that do not fit
    its data, and for a non-finite point in a message flagged IS_STRICTLY_FINITE.
    """
    message = POINT_CLOUD.strict.decode(data)
    layout = Layout(
        fields=tuple(PointField(f.name, f.byte_offset, f.datatype, f.count) for f in message.fields),
        width=message.width,
        height=message.height,
        point_step=message.point_step,
        row_step=message.row_step,
        big_endian=bool(message.flags & IS_BIGENDIAN),
    )
    cloud = read_points(
        message.data,
        layout,
        type_name=TYPE_NAME,
        rgb_order=DRAKE_RGB,
        finite_claimed=bool(message.flags & IS_STRICTLY_FINITE),
    )
    return StampedPointCloud(cloud, frame_name(message.frame_name), message.utime)


def cloud_to_lcm(stamped: StampedPointCloud) -> bytes:
    """A stamped cloud as an encoded `lcmt_point_cloud`, laid out as PointCloudToLcm lays it out."""
    fields, point_step, data = write_points(stamped.cloud, DRAKE_RGB, UINT32)
    message = POINT_CLOUD.message_class(
        utime=int(stamped.time_us),
        frame_name=stamped.frame,
        width=len(stamped.cloud),
        height=1,
        num_fields=len(fields),
        fields=[
            POINT_CLOUD_FIELD.message_class(
                name=field.name, byte_offset=field.offset, datatype=field.datatype, count=field.count
            )
            for field in fields
        ],
        flags=IS_STRICTLY_FINITE,  # a scene's points are finite
        point_step=point_step,
        row_step=len(data),
        filler_size=0,
        filler=b"",
        data_size=0,
        data=b"",
    )
    # The encoded size so far includes the 8-byte data_size; filler goes before that.
    filler = -len(POINT_CLOUD.encode(message)) % _DATA_ALIGNMENT
    message.filler_size, message.filler = filler, b"\0" * filler
    message.data_size, message.data = len(data), data
    return POINT_CLOUD.encode(message)
