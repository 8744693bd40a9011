"""The point layout Drake's `lcmt_point_cloud` and ROS's `sensor_msgs/PointCloud2` share.

Both describe a point as named fields at byte offsets within `point_step` bytes, rows
`row_step` bytes apart, with the same datatype codes (PCL's: INT8 = 1 ... FLOAT64 = 8). So one
reader and one writer serve both formats, on numpy views of the message's bytes; a format says
only where r, g and b sit in the 4 bytes of its `rgb` field and which datatype it gives that field.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from viewer_bridge.errors import DecodeError
from viewer_bridge.model.scene import FloatArray, PointCloud

# The datatype codes of lcmt_point_cloud_field and sensor_msgs/PointField (equal in both specs).
DATATYPES: dict[int, str] = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
UINT32 = 6
FLOAT32 = 7

XYZ = ("x", "y", "z")
NORMALS = ("normal_x", "normal_y", "normal_z")
RGB_NAMES = ("rgb", "rgba")  # PCL's PointXYZRGB and PointXYZRGBA; alpha is not kept

# Where r, g and b sit among the 4 bytes of the rgb field, in memory order.
RgbOrder = tuple[int, int, int]
DRAKE_RGB: RgbOrder = (0, 1, 2)  # PointCloudToLcm writes the bytes r, g, b, 0
PCL_RGB_LITTLE: RgbOrder = (2, 1, 0)  # PCL packs 0x00RRGGBB in a word: b, g, r, 0 little-endian
PCL_RGB_BIG: RgbOrder = (1, 2, 3)


_MAX_POINT_STEP = 2**31 - 1  # numpy's largest record (a C int)


@dataclass(frozen=True, slots=True)
class PointField:
    name: str
    offset: int  # bytes from the start of a point
    datatype: int  # a key of DATATYPES
    count: int = 1


@dataclass(frozen=True, slots=True)
class Layout:
    """What a message's header says about its point bytes."""

    fields: tuple[PointField, ...]
    width: int
    height: int
    point_step: int
    row_step: int
    big_endian: bool = False


class _Reader:
    """Checks a layout against its bytes; every refusal is a `DecodeError` of `type_name`."""

    def __init__(self, layout: Layout, type_name: str, data_field: str) -> None:
        self.layout = layout
        self.type_name = type_name
        self.data_field = data_field

    def fail(self, field: str, offset: int, reason: str, unit: str = "byte") -> DecodeError:
        return DecodeError(self.type_name, field, offset, reason, unit)

    def check_shape(self, size: int) -> int:
        """The number of points, once the sizes fit the bytes (before anything is allocated)."""
        layout = self.layout
        for name in ("width", "height", "point_step", "row_step"):
            if getattr(layout, name) < 0:
                raise self.fail(name, 0, f"{getattr(layout, name)} is negative")
        if layout.point_step > _MAX_POINT_STEP:  # found by bench/fuzz.py: numpy's limit for a record
            raise self.fail(
                "point_step", 0, f"{layout.point_step} is more than {_MAX_POINT_STEP} bytes a point"
            )
        count = layout.width * layout.height
        if count and layout.point_step == 0:
            raise self.fail("point_step", 0, "0 for a cloud with points")
        if layout.row_step < layout.width * layout.point_step:
            raise self.fail(
                "row_step",
                0,
                f"{layout.row_step} is less than width x point_step = {layout.width * layout.point_step}",
            )
        if size != layout.row_step * layout.height:
            raise self.fail(
                self.data_field, 0, f"{size} bytes, but row_step x height = {layout.row_step * layout.height}"
            )
        return count

    def field(self, name: str, required: bool) -> PointField | None:
        """The field `name`, checked to fit inside a point; None if absent and not required."""
        for index, candidate in enumerate(self.layout.fields):
            if candidate.name != name:
                continue
            where = f"fields[{index}]"
            if candidate.datatype not in DATATYPES:
                raise self.fail(f"{where}.datatype", 0, f"{candidate.datatype} is not a datatype (1..8)")
            if candidate.count != 1:
                raise self.fail(f"{where}.count", 0, f"{name!r} must have count 1, not {candidate.count}")
            size = 4 if name in RGB_NAMES else np.dtype(DATATYPES[candidate.datatype]).itemsize
            if candidate.offset < 0 or candidate.offset + size > self.layout.point_step:
                raise self.fail(
                    f"{where}.offset",
                    0,
                    f"{name!r} at {candidate.offset} ({size} bytes) is outside point_step {self.layout.point_step}",
                )
            return candidate
        if required:
            names = [candidate.name for candidate in self.layout.fields]
            raise self.fail("fields", 0, f"no {name!r} field (fields: {names})")
        return None


def read_points(
    data: bytes | memoryview,
    layout: Layout,
    *,
    type_name: str,
    rgb_order: RgbOrder,
    finite_claimed: bool = False,
    data_field: str = "data",
) -> PointCloud:
    """The points (and colours, normals, where there are fields for them) of a message's bytes.

    A point whose x, y, z or normal is not finite is left out (depth cameras send NaN for "no
    return"), unless the message claims its points are finite (`finite_claimed`): then a
    non-finite x, y or z is a lie, and a `DecodeError` naming the point. Sizes that do not fit
    the bytes, unknown datatypes and fields outside a point are `DecodeError`s too.
    """
    reader = _Reader(layout, type_name, data_field)
    count = reader.check_shape(len(data))
    if count == 0 and not layout.fields:  # a default-constructed message: nothing to look up
        return PointCloud(np.empty((0, 3)))
    xyz = [reader.field(name, required=True) for name in XYZ]
    rgb = reader.field("rgb", False) or reader.field("rgba", False)
    normal_fields = [reader.field(name, required=False) for name in NORMALS]
    normals_present = all(normal_fields)
    wanted: list[PointField] = [field for field in xyz if field is not None]
    if normals_present:
        wanted += [field for field in normal_fields if field is not None]
    table = np.ndarray(
        shape=(layout.height, layout.width),
        dtype=_structured_dtype(wanted, rgb, layout),
        buffer=data,
        strides=(layout.row_step, layout.point_step),
    ).reshape(count)
    points = _columns(table, XYZ)
    normals = _columns(table, NORMALS) if normals_present else None
    colors = None if rgb is None else table["rgb"][:, list(rgb_order)] / 255.0
    if _all_finite(points, normals):  # the common case, checked with flat (fast) reductions
        return PointCloud(points, colors, normals=normals)
    finite = np.isfinite(points).all(axis=1)
    if finite_claimed and not finite.all():
        row = int(np.flatnonzero(~finite)[0])
        raise reader.fail(data_field, row, "not finite, though the message says every point is", "point")
    if normals is not None:
        finite &= np.isfinite(normals).all(axis=1)
    return PointCloud(
        points[finite],
        None if colors is None else colors[finite],
        normals=None if normals is None else normals[finite],
    )


def _all_finite(points: FloatArray, normals: FloatArray | None) -> bool:
    return bool(np.isfinite(points).all() and (normals is None or np.isfinite(normals).all()))


def _structured_dtype(fields: Sequence[PointField], rgb: PointField | None, layout: Layout) -> np.dtype[Any]:
    order = ">" if layout.big_endian else "<"
    names = [field.name for field in fields]
    formats: list[Any] = [order + DATATYPES[field.datatype] for field in fields]
    offsets = [field.offset for field in fields]
    if rgb is not None:  # the 4 bytes as they are: the format says which is r, g and b
        names.append("rgb")
        formats.append(("u1", 4))
        offsets.append(rgb.offset)
    return np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": layout.point_step})


def _columns(table: npt.NDArray[Any], names: Sequence[str]) -> FloatArray:
    result = np.empty((len(table), len(names)), dtype=np.float64)
    with np.errstate(invalid="ignore"):  # NaN and infinity are sorted out by the caller
        for column, name in enumerate(names):
            result[:, column] = table[name]
    return result


def write_points(
    cloud: PointCloud, rgb_order: RgbOrder, rgb_datatype: int
) -> tuple[tuple[PointField, ...], int, bytes]:
    """(fields, point_step, bytes) of a cloud, little-endian, in Drake's field order.

    x, y, z as FLOAT32 at 0, 4, 8; then `rgb` (4 bytes, `rgb_order`, typed `rgb_datatype`) if
    the cloud has colours; then normal_x, normal_y, normal_z as FLOAT32 if it has normals. This is
    PointCloudToLcm's layout, which meldis requires, and what RViz and PCL read.
    """
    fields = [PointField(name, 4 * index, FLOAT32) for index, name in enumerate(XYZ)]
    if cloud.colors is not None:
        fields.append(PointField("rgb", 12, rgb_datatype))
    if cloud.normals is not None:
        start = 4 * len(fields)
        fields += [PointField(name, start + 4 * index, FLOAT32) for index, name in enumerate(NORMALS)]
    point_step = 4 * len(fields)
    # One float32 table, N x (3, 4, 6 or 7) columns; the rgb column is written as the 32-bit word
    # whose little-endian bytes are r, g, b where `rgb_order` puts them (one vector op per channel).
    table = np.empty((len(cloud), len(fields)), dtype="<f4")
    table[:, :3] = cloud.points
    if cloud.colors is not None:
        scaled = cloud.colors * 255.0
        scaled += 0.5  # rounds (colours are >= 0); several times faster than np.rint here
        channels = scaled.astype(np.uint32)
        word = channels[:, 0] << (8 * rgb_order[0])
        word |= channels[:, 1] << (8 * rgb_order[1])
        word |= channels[:, 2] << (8 * rgb_order[2])
        table.view("<u4")[:, 3] = word
    if cloud.normals is not None:
        table[:, -3:] = cloud.normals
    return tuple(fields), point_step, table.tobytes()
