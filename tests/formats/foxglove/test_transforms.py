"""The FrameTransforms fast path against the message the protobuf classes build."""

from __future__ import annotations

import numpy as np
import pytest
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

from tests.formats.foxglove.oracle import frame_transforms
from viewer_bridge.formats.foxglove.transforms import FrameTransformsEncoder
from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.model.scene import LinkPoses


def _poses(names: tuple[str, ...], seed: int) -> LinkPoses:
    rng = np.random.default_rng(seed)
    quaternions = rng.normal(size=(len(names), 4))
    quaternions /= np.sqrt((quaternions**2).sum(axis=1, keepdims=True))
    robot_nums = np.zeros(len(names), dtype=np.int32)
    return LinkPoses(0, names, robot_nums, rng.normal(size=(len(names), 3)) * 10, quaternions)


@pytest.mark.parametrize("stamp", [(0, 0), (12, 500_000_000), (2**31 - 1, 999_999_999), (-3, 7)])
def test_the_encoder_writes_the_message_the_protobuf_classes_build(stamp: tuple[int, int]) -> None:
    frames = FrameNames(prefix="sim/")
    encoder = FrameTransformsEncoder(frames)
    # Name sets change between draws (a new template each time) and come back (the kept one).
    for seed, names in enumerate([("a::b", "a::c"), ("world", "x"), ("a::b", "a::c"), ()]):
        poses = _poses(names, seed)
        written = FrameTransforms()
        written.ParseFromString(encoder.encode(poses, stamp))
        assert written == frame_transforms(poses, stamp, frames)
