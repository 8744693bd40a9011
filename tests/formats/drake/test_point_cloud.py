"""Drake's `lcmt_point_cloud` (viewer_bridge/formats/drake/point_cloud.py) against pydrake's
PointCloudToLcm: read, written back byte for byte, and the checks on bad input."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.optional import peer
from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm, cloud_to_lcm
from viewer_bridge.lcmcodec.codecs import POINT_CLOUD
from viewer_bridge.model.scene import StampedPointCloud
from viewer_bridge.transports.lcm import LcmEvent, write_log

# Drake's own lcm-gen classes, shipped with pydrake: imported by the tests that use them
drake_lcmtypes = peer("drake")

FIELDS = {
    "xyz": ("kXYZs",),
    "xyz_rgb": ("kXYZs", "kRGBs"),
    "xyz_rgb_normals": ("kXYZs", "kRGBs", "kNormals"),
}


def pydrake_message(kinds: tuple[str, ...], count: int = 40, seed: int = 0, time_s: float = 0.5) -> bytes:
    """What pydrake's PointCloudToLcm publishes (through the C++ serializer) for a random cloud."""
    from pydrake.lcm import DrakeLcm
    from pydrake.perception import BaseField, Fields
    from pydrake.perception import PointCloud as DrakePointCloud

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
    pydrake_publisher(lcm, "CLOUD", cloud, "plant::camera", time_s)()
    lcm.HandleSubscriptions(0)
    return received[0]


def pydrake_publisher(
    lcm: Any, channel: str, cloud: Any, frame_name: str, time_s: float
) -> Callable[[], None]:
    """A diagram of pydrake's PointCloudToLcm and LcmPublisherSystem (C++ serializer) holding
    `cloud` at `time_s`; returns what publishes it once on `channel`."""
    from pydrake.common.value import AbstractValue
    from pydrake.perception import PointCloudToLcm
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.lcm import LcmPublisherSystem

    builder = DiagramBuilder()
    to_lcm = builder.AddSystem(PointCloudToLcm(frame_name=frame_name))
    publisher = builder.AddSystem(
        LcmPublisherSystem.Make(
            channel=channel,
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
    return lambda: diagram.ForcedPublish(context)


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
        [sys.executable, "-m", "viewer_bridge.cli.main", "dump", str(log), "--json"],
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
