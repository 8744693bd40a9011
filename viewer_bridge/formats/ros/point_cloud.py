"""ROS 2's `sensor_msgs/PointCloud2` CDR <-> the neutral `StampedPointCloud`, straight from bytes.

Written: one unorganised row (`height` 1), x, y, z FLOAT32 at 0, 4, 8, `rgb` at 12 as PCL packs
it (0x00RRGGBB in a little-endian word, typed FLOAT32 as PCL's PointXYZRGB is, which RViz and
`pcl_conversions` both read), normals after it; `is_dense` true (a scene's points are finite).
Read: any field layout, either byte order, organised or not; points that are not finite (a
depth camera's "no return") are left out, since a scene holds only finite points.
"""

from __future__ import annotations

from viewer_bridge.formats.point_fields import (
    FLOAT32,
    PCL_RGB_BIG,
    PCL_RGB_LITTLE,
    Layout,
    PointField,
    read_points,
    write_points,
)
from viewer_bridge.formats.ros.cdr import CdrReader, time_parts_from_us
from viewer_bridge.formats.ros.message_types import POINT_CLOUD2
from viewer_bridge.lcmcodec.ros_writer import ros_writer
from viewer_bridge.model.scene import StampedPointCloud

_SMALLEST_POINT_FIELD = 13  # name (length + NUL), offset, datatype, count: never fewer bytes


def cloud_to_cdr(stamped: StampedPointCloud, default_frame: str = "world") -> bytes:
    """A stamped cloud as PointCloud2 CDR (frame `default_frame` when the cloud names none)."""
    fields, point_step, data = write_points(stamped.cloud, PCL_RGB_LITTLE, FLOAT32)
    header = (time_parts_from_us(stamped.time_us), stamped.frame or default_frame)
    point_fields = [(field.name, field.offset, field.datatype, field.count) for field in fields]
    big_endian, dense = False, True
    value = (header, 1, len(stamped.cloud), point_fields, big_endian, point_step, len(data), data, dense)
    return ros_writer(POINT_CLOUD2).write(value)  # height 1, width: one unorganised row


def cloud_from_cdr(data: bytes | memoryview) -> StampedPointCloud:
    """PointCloud2 CDR as a stamped cloud.

    Raises `DecodeError` naming the field for bytes that are not a PointCloud2, sizes that do not
    fit its data, unknown datatypes, or a cloud without x, y and z.
    """
    reader = CdrReader(data, POINT_CLOUD2)
    time_us, frame = reader.header()
    height = reader.scalar("I", "height")
    width = reader.scalar("I", "width")
    fields = tuple(
        PointField(
            reader.string(f"fields[{index}].name"),
            reader.scalar("I", f"fields[{index}].offset"),
            reader.scalar("B", f"fields[{index}].datatype"),
            reader.scalar("I", f"fields[{index}].count"),
        )
        for index in range(reader.count("fields", _SMALLEST_POINT_FIELD))
    )
    big_endian = reader.boolean("is_bigendian")
    point_step = reader.scalar("I", "point_step")
    row_step = reader.scalar("I", "row_step")
    points = reader.octets("data")
    reader.boolean("is_dense")  # not trusted: finiteness is checked point by point
    layout = Layout(fields, width, height, point_step, row_step, big_endian)
    rgb_order = PCL_RGB_BIG if big_endian else PCL_RGB_LITTLE
    cloud = read_points(points, layout, type_name=POINT_CLOUD2, rgb_order=rgb_order)
    return StampedPointCloud(cloud, frame, time_us)
