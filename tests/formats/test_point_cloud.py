"""Point clouds: Drake's lcmt_point_cloud (against pydrake's PointCloudToLcm), the shared field reader,
the checks on bad input, and clouds through ROS and back (ROS's PointCloud2 itself:
tests/formats/ros/test_point_cloud.py)."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest

from bridge.errors import DecodeError, SceneError
from bridge.formats.drake_point_cloud import cloud_from_lcm, cloud_to_lcm
from bridge.formats.ros.point_cloud import cloud_from_cdr, cloud_to_cdr
from bridge.lcmcodec import POINT_CLOUD
from bridge.scene import PointCloud, StampedPointCloud
from bridge.transports.lcm import LcmEvent, write_log

FIELDS = {
    "xyz": ("kXYZs",),
    "xyz_rgb": ("kXYZs", "kRGBs"),
    "xyz_rgb_normals": ("kXYZs", "kRGBs", "kNormals"),
}


def pydrake_message(kinds: tuple[str, ...], count: int = 40, seed: int = 0, time_s: float = 0.5) -> bytes:
    """What pydrake's PointCloudToLcm publishes (through the C++ serializer) for a random cloud."""
    from pydrake.common.value import AbstractValue
    from pydrake.lcm import DrakeLcm
    from pydrake.perception import BaseField, Fields, PointCloudToLcm
    from pydrake.perception import PointCloud as DrakePointCloud
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.lcm import LcmPublisherSystem

    rng = np.random.default_rng(seed)
    bits = 0
    for kind in kinds:
        bits |= getattr(BaseField, kind)
    cloud = DrakePointCloud(count, Fields(bits))
    cloud.mutable_xyzs()[:] = rng.uniform(-3, 3, (3, count))
    if "kRGBs" in kinds:
        cloud.mutable_rgbs()[:] = rng.integers(0, 256, (3, count))
    if "kNormals" in kinds:
        normals = rng.normal(size=(3, count))
        cloud.mutable_normals()[:] = normals / np.linalg.norm(normals, axis=0)
    lcm = DrakeLcm("memq://")
    received: list[bytes] = []
    lcm.Subscribe("CLOUD", received.append)
    builder = DiagramBuilder()
    to_lcm = builder.AddSystem(PointCloudToLcm(frame_name="plant::camera"))
    publisher = builder.AddSystem(
        LcmPublisherSystem.Make(
            channel="CLOUD",
            lcm_type=drake_lcmtypes.lcmt_point_cloud,
            lcm=lcm,
            publish_period=0.0,
            use_cpp_serializer=True,
        )
    )
    builder.Connect(to_lcm.get_output_port(), publisher.get_input_port())
    builder.ExportInput(to_lcm.get_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    context.SetTime(time_s)
    diagram.get_input_port().FixValue(context, AbstractValue.Make(cloud))
    diagram.ForcedPublish(context)
    lcm.HandleSubscriptions(0)
    return received[0]


def sample_cloud(count: int = 30, colors: bool = True, normals: bool = False, seed: int = 3) -> PointCloud:
    rng = np.random.default_rng(seed)
    points = rng.uniform(-5, 5, (count, 3)).astype(np.float32).astype(np.float64)  # float32 on the wire
    normal_rows = rng.normal(size=(count, 3)).astype(np.float32).astype(np.float64)
    return PointCloud(
        points,
        rng.integers(0, 256, (count, 3)) / 255.0 if colors else None,
        normals=normal_rows if normals else None,
    )


# --- Drake ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kinds", FIELDS.values(), ids=list(FIELDS))
def test_drake_clouds_read_and_are_written_back_byte_for_byte(kinds: tuple[str, ...]) -> None:
    data = pydrake_message(kinds)
    theirs = drake_lcmtypes.lcmt_point_cloud.decode(data)
    stamped = cloud_from_lcm(data)
    raw = np.frombuffer(theirs.data, dtype=np.float32).reshape(-1, theirs.num_fields)
    np.testing.assert_array_equal(stamped.cloud.points, raw[:, :3])
    assert (stamped.cloud.colors is not None) == ("kRGBs" in kinds)
    if stamped.cloud.colors is not None:
        rgb = raw[:, 3].astype(np.float32).view(np.uint8).reshape(-1, 4)[:, :3]  # as meldis reads it
        np.testing.assert_array_equal(np.rint(stamped.cloud.colors * 255), rgb)
    if "kNormals" in kinds:
        np.testing.assert_array_equal(stamped.cloud.normals, raw[:, 4:])
    assert (stamped.frame, stamped.time_us) == ("plant/camera", 500_000)
    # Written back: exactly what PointCloudToLcm wrote (filler included), with the frame as sent.
    again = cloud_to_lcm(StampedPointCloud(stamped.cloud, "plant::camera", stamped.time_us))
    assert again == data


def test_drake_cloud_flagged_finite_with_a_nan_is_refused_naming_the_point() -> None:
    message = POINT_CLOUD.decode(pydrake_message(("kXYZs",), count=5))
    values = bytearray(message.data)
    values[3 * 12 + 4 : 3 * 12 + 8] = struct.pack("<f", float("nan"))  # point 3's y
    message.data = bytes(values)
    with pytest.raises(DecodeError, match=r"data at point 3: not finite") as caught:
        cloud_from_lcm(POINT_CLOUD.encode(message))
    assert caught.value.type_name == "drake.lcmt_point_cloud"
    message.flags = 0  # not claimed finite: the point is left out, as PointCloudToLcm leaves it out
    assert len(cloud_from_lcm(POINT_CLOUD.encode(message)).cloud) == 4


def _edited(change: dict[str, Any]) -> bytes:
    message = POINT_CLOUD.decode(pydrake_message(("kXYZs", "kRGBs"), count=4))
    for name, value in change.items():
        if name.startswith("fields."):
            setattr(message.fields[3], name.removeprefix("fields."), value)
        else:
            setattr(message, name, value)
    return POINT_CLOUD.encode(message)


@pytest.mark.parametrize(
    ("change", "field", "reason"),
    [
        ({"width": 2**31, "row_step": 16 * 2**31}, "data", "row_step x height"),
        ({"height": 2**40}, "data", "row_step x height"),
        ({"height": -1}, "height", "negative"),
        ({"point_step": 0}, "point_step", "0 for a cloud with points"),
        ({"row_step": 8}, "row_step", "less than width x point_step"),
        ({"fields.datatype": 9}, "fields[3].datatype", "not a datatype"),
        ({"fields.byte_offset": 14}, "fields[3].offset", "outside point_step"),
        ({"fields.count": 3}, "fields[3].count", "count 1"),
    ],
)
def test_drake_cloud_with_sizes_that_do_not_fit_is_a_decode_error(
    change: dict[str, Any], field: str, reason: str
) -> None:
    with pytest.raises(DecodeError, match=reason) as caught:
        cloud_from_lcm(_edited(change))
    assert caught.value.field == field


def test_drake_cloud_claiming_2_to_the_31_bytes_is_refused_before_allocating() -> None:
    message = POINT_CLOUD.decode(pydrake_message(("kXYZs",), count=4))
    data = POINT_CLOUD.encode(message)
    claim = data[: -8 - message.data_size] + struct.pack(">q", 2**31) + message.data
    with pytest.raises(DecodeError, match="2147483648") as caught:
        cloud_from_lcm(claim)
    assert caught.value.field == "data"


def test_a_cloud_without_xyz_is_refused_naming_the_fields() -> None:
    with pytest.raises(DecodeError, match=r"no 'x' field \(fields: \['q', 'y', 'z', 'rgb'\]\)"):
        message = POINT_CLOUD.decode(pydrake_message(("kXYZs", "kRGBs"), count=2))
        message.fields[0].name = "q"
        cloud_from_lcm(POINT_CLOUD.encode(message))


def test_dump_decodes_a_point_cloud(tmp_path: Path) -> None:
    log = tmp_path / "cloud.lcmlog"
    write_log(log, [LcmEvent("DRAKE_POINT_CLOUD", pydrake_message(("kXYZs", "kRGBs"), count=3), 1)])
    result = subprocess.run(
        [sys.executable, "-m", "bridge.cli", "dump", str(log), "--json"],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    assert result.returncode == 0, result.stderr
    (record,) = [json.loads(line) for line in result.stdout.splitlines()]
    assert record["type"] == "drake.lcmt_point_cloud"
    message = record["message"]
    assert (message["width"], message["point_step"], message["frame_name"]) == (3, 16, "plant::camera")
    assert [field["name"] for field in message["fields"]] == ["x", "y", "z", "rgb"]


# --- the scene model's checks -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"points": np.zeros((2, 2))}, r"points must be N x 3, got shape \(2, 2\)"),
        ({"points": np.array([[0, 0, 0], [np.inf, 0, 0]])}, r"points\[1\] is not finite"),
        ({"colors": np.array([[0, 0, 0], [0, 2, 0]])}, r"colors\[1\] is outside \[0, 1\]"),
        ({"colors": np.zeros((3, 3))}, r"colors must be 2 x 3 \(one row per point\)"),
        ({"normals": np.array([[np.nan, 0, 1], [0, 0, 1]])}, r"normals\[0\] is not finite"),
    ],
)
def test_point_cloud_checks_its_arrays(kwargs: dict[str, Any], message: str) -> None:
    values = {"points": np.zeros((2, 3)), **kwargs}
    with pytest.raises(SceneError, match=message):
        PointCloud(**values)


@pytest.mark.parametrize("count", [0, 1, 2, 257])
@pytest.mark.parametrize(("colors", "normals"), [(False, False), (True, False), (False, True), (True, True)])
def test_clouds_survive_drake_to_ros_to_drake(count: int, colors: bool, normals: bool) -> None:
    cloud = sample_cloud(count, colors=colors, normals=normals, seed=count)
    stamped = StampedPointCloud(cloud, "plant/camera", 123_456_000)
    via_ros = cloud_from_cdr(cloud_to_cdr(cloud_from_lcm(cloud_to_lcm(stamped))))
    assert via_ros.cloud == cloud  # colours and normals kept, even for an empty cloud
    assert (via_ros.frame, via_ros.time_us) == ("plant/camera", 123_456_000)
    theirs = drake_lcmtypes.lcmt_point_cloud.decode(cloud_to_lcm(via_ros))
    assert theirs.width == count and theirs.point_step == 12 + 4 * colors + 12 * normals
