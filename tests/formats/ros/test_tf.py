"""TF from Drake's link poses: the TFMessage fast path against the objects, and the frame names."""

from __future__ import annotations

import numpy as np
import pytest

from tests.formats.ros.oracle import transforms_message
from viewer_bridge.formats.ros.messages import to_cdr
from viewer_bridge.formats.ros.tf import FrameNames, TransformsEncoder
from viewer_bridge.model.scene import LinkPoses


def random_poses(count: int, seed: int) -> LinkPoses:
    generator = np.random.default_rng(seed)
    wxyz = generator.normal(size=(count, 4))
    wxyz /= np.linalg.norm(wxyz, axis=1)[:, None]
    names = tuple(f"plant::robot{index % 3}::link_{index}" for index in range(count))
    return LinkPoses(7_250, names, np.ones(count, np.int32), generator.normal(size=(count, 3)), wxyz)


@pytest.mark.parametrize("count", [0, 1, 7, 1000])
def test_tf_fast_path_equals_the_objects(count: int) -> None:
    frames = FrameNames("map", "proximity/")
    encoder = TransformsEncoder(frames)
    for stamp in ((12, 500_000_000), (-3, 999_999_999)):  # the template is rewritten, not rebuilt
        poses = random_poses(count, seed=count)
        assert encoder.encode(poses, stamp) == to_cdr(transforms_message(poses, stamp, frames))


def test_one_tf_encoder_follows_changing_links_and_poses() -> None:
    """The encoder keeps its message between draws: nothing of one draw may show in the next."""
    frames = FrameNames()
    encoder = TransformsEncoder(frames)
    for seed, count in enumerate((3, 1000, 1000, 3, 0, 7)):
        poses = random_poses(count, seed=seed)
        stamp = (seed, 1000 * seed)
        assert encoder.encode(poses, stamp) == to_cdr(transforms_message(poses, stamp, frames))


def test_frame_names() -> None:
    assert FrameNames()("plant::iiwa::iiwa_link_0") == "plant/iiwa/iiwa_link_0"
    assert FrameNames("map", "proximity/")("world") == "map"
    assert FrameNames("map", "proximity/")("plant::a") == "proximity/plant/a"
