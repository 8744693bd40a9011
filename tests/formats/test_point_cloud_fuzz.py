"""Fuzzing the point cloud decoders: only `DecodeError` escapes, memory stays bounded.

The same mutations as `tests/lcmcodec/test_fuzz.py` (flips, cuts, extreme counts, noise), on a
small cloud of each format: Drake's lcmt_point_cloud (as PointCloudToLcm writes it) and ROS's
PointCloud2 CDR (with colours and normals, so every field reader is reached).
"""

from __future__ import annotations

import resource
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from tests.formats.drake.test_point_cloud import pydrake_message
from tests.formats.test_point_cloud import sample_cloud
from tests.lcmcodec.test_fuzz import BUFFERS_PER_DECODER, mutate
from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr, cloud_to_cdr
from viewer_bridge.model.scene import StampedPointCloud


def seeds() -> dict[str, bytes]:
    return {
        "lcmt_point_cloud": pydrake_message(("kXYZs", "kRGBs", "kNormals"), count=6),
        "PointCloud2": cloud_to_cdr(StampedPointCloud(sample_cloud(6, normals=True), "camera", 1_000)),
    }


DECODERS: dict[str, Callable[[bytes], Any]] = {
    "lcmt_point_cloud": cloud_from_lcm,
    "PointCloud2": cloud_from_cdr,
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(DECODERS))
def test_only_decode_errors_escape(name: str) -> None:
    decode = DECODERS[name]
    seed = seeds()[name]
    assert len(decode(seed).cloud) == 6  # the seed itself is valid
    rng = np.random.default_rng(sum(name.encode()))
    before_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    outcomes = {"decoded": 0, "rejected": 0}
    for _ in range(BUFFERS_PER_DECODER):
        data = mutate(rng, seed)
        try:
            decode(data)
            outcomes["decoded"] += 1
        except DecodeError:
            outcomes["rejected"] += 1
    grown_mib = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before_kib) / 1024
    assert outcomes["rejected"] > BUFFERS_PER_DECODER // 2  # the mutations really were bad...
    assert outcomes["decoded"] > 0  # ...but not all of them: the fuzzer reaches valid inputs too
    assert grown_mib < 64, f"peak memory grew by {grown_mib:.0f} MiB"
