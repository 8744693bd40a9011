"""The tree viewer's fast settransform path against the reference (`encode(draw_request(...))`)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bridge.formats import tree_viewer as tv
from bridge.formats.drake import DrawDecoder, DrawEncoder
from bridge.scene import LinkPoses
from tests.conftest import Capture
from tests.strategies import link_poses


def reference(poses: LinkPoses, prefix: tuple[str, ...], utime: int = 0) -> bytes:
    return tv.encode(tv.draw_request(poses, prefix, utime))


@settings(max_examples=200, deadline=None)
@given(st.lists(link_poses(max_links=8), min_size=1, max_size=4), st.sampled_from([(), ("drake",), ('a"\\', "é")]))
def test_settransform_bytes_equal_the_reference(frames: list[LinkPoses], prefix: tuple[str, ...]) -> None:
    encoder = tv.SettransformEncoder(prefix)  # one encoder for all frames: its template must follow the links
    for poses in frames:
        assert encoder.encode(poses) == reference(poses, prefix)
        assert encoder.encode(poses, utime=7) == reference(poses, prefix, 7)


def test_settransform_of_real_drake_draws_through_the_decoder(drake_capture: dict[str, Capture]) -> None:
    for capture in drake_capture.values():
        poses = DrawDecoder().decode(DrawEncoder().encode(capture.poses))  # the decoder's float32 arrays
        assert poses.positions.dtype == np.dtype(np.float32)
        encoder = tv.SettransformEncoder()
        assert encoder.encode(poses) == reference(poses, tv.DEFAULT_PREFIX)
        moved = LinkPoses(poses.timestamp_ms + 1, poses.names, poses.robot_nums, poses.positions * 2, poses.quaternions_wxyz)
        assert encoder.encode(moved) == reference(moved, tv.DEFAULT_PREFIX)


def test_unusual_numbers_are_written_as_the_reference_writes_them() -> None:
    values = [0.0, -0.0, 1e-7, 1e300, 5e-324, 123456789012345680.0, 1.0, -2.5]
    positions = np.array(values[:6], dtype=np.float64).reshape(2, 3)
    quaternions = np.array(values, dtype=np.float64).reshape(2, 4)
    poses = LinkPoses(3, ("a", 'b"\n\\'), np.array([0, -1], dtype=np.int32), positions, quaternions)
    assert tv.SettransformEncoder().encode(poses) == reference(poses, tv.DEFAULT_PREFIX)
    empty = LinkPoses(3, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))
    assert tv.SettransformEncoder().encode(empty) == reference(empty, tv.DEFAULT_PREFIX)
