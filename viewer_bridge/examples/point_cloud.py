"""Example `point_cloud`: a coloured point cloud, published the way Drake publishes one.

`viewer-bridge example point_cloud` runs it: a ring of 2000 points, coloured by angle, turning
about z, sent ten times a second through pydrake's `PointCloudToLcm` and `LcmPublisherSystem`
(Drake's C++ serializer) on `DRAKE_POINT_CLOUD_EXAMPLE`, in the frame `world`: what meldis shows,
and what the default config routes to `/drake/point_cloud/example`.
"""

from __future__ import annotations

import math
import time

import numpy as np

CHANNEL = "DRAKE_POINT_CLOUD_EXAMPLE"
POINTS = 2000
RATE_HZ = 10.0


def ring(angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Points (3 x N, metres) on a wavy ring turned by `angle`, and their colours (3 x N, uint8)."""
    around = np.linspace(0.0, 2 * math.pi, POINTS, endpoint=False)
    xyz = np.stack(
        [0.5 * np.cos(around + angle), 0.5 * np.sin(around + angle), 0.3 + 0.05 * np.sin(5 * around)]
    )
    rgb = np.stack([127 + 127 * np.cos(around + shift) for shift in (0.0, 2.1, 4.2)]).astype(np.uint8)
    return xyz.astype(np.float32), rgb


def run(url: str, seconds: float) -> None:
    """Publish the turning ring on `url` for `seconds`, in real time."""
    import drake as drake_lcmtypes  # Drake's LCM message classes, installed with pydrake
    from pydrake.common.value import AbstractValue
    from pydrake.lcm import DrakeLcm
    from pydrake.perception import BaseField, Fields, PointCloud, PointCloudToLcm
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.lcm import LcmPublisherSystem

    builder = DiagramBuilder()
    to_lcm = builder.AddSystem(PointCloudToLcm(frame_name="world"))
    publisher = builder.AddSystem(
        LcmPublisherSystem.Make(
            channel=CHANNEL,
            lcm_type=drake_lcmtypes.lcmt_point_cloud,
            lcm=DrakeLcm(url),
            publish_period=0.0,
            use_cpp_serializer=True,
        )  # fmt: skip
    )
    builder.Connect(to_lcm.get_output_port(), publisher.get_input_port())
    builder.ExportInput(to_lcm.get_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    cloud = PointCloud(POINTS, Fields(BaseField.kXYZs | BaseField.kRGBs))
    start = time.monotonic()
    while (elapsed := time.monotonic() - start) < seconds:
        xyz, rgb = ring(0.5 * elapsed)
        cloud.mutable_xyzs()[:] = xyz
        cloud.mutable_rgbs()[:] = rgb
        context.SetTime(elapsed)
        diagram.get_input_port().FixValue(context, AbstractValue.Make(cloud))
        diagram.ForcedPublish(context)
        time.sleep(max(0.0, 1.0 / RATE_HZ - (time.monotonic() - start - elapsed)))
