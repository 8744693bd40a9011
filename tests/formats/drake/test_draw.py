"""Drake's `lcmt_viewer_draw` (viewer_bridge/formats/drake/draw.py): the fast decoder and encoder against
Drake's traffic, Drake's own class and the reference (tests/formats/drake/oracle.py)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tests.formats.drake.oracle import draw_from_poses
from tests.optional import peer
from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder, poses_from_draw
from viewer_bridge.lcmcodec.codecs import DRAW
from viewer_bridge.model.scene import frame_name
from viewer_bridge.transports.lcm import LcmEvent

# Drake's own lcm-gen classes, shipped with pydrake: imported by the tests that use them
drake_lcmtypes = peer("drake")


def test_draw_fast_path_matches_drake(drake_events: list[LcmEvent]) -> None:
    decoder = DrawDecoder()
    encoder = DrawEncoder()
    draws = [e for e in drake_events if e.channel == "DRAKE_VIEWER_DRAW_ILLUSTRATION"]
    assert len({e.data for e in draws}) > 1  # the bodies fall: frames differ
    for event in draws:
        theirs = drake_lcmtypes.lcmt_viewer_draw.decode(event.data)
        poses = decoder.decode(event.data)
        assert poses.names == tuple(theirs.link_name)
        assert poses.robot_nums.tolist() == list(theirs.robot_num)
        assert poses.positions.tolist() == [list(p) for p in theirs.position]
        assert poses.quaternions_wxyz.tolist() == [list(q) for q in theirs.quaternion]
        assert not poses.positions.flags.owndata  # a view into the buffer, not a copy
        assert encoder.encode(poses) == event.data
        assert draw_from_poses(poses_from_draw(DRAW.decode(event.data))).encode() == event.data
    assert all("::" in name for name in poses.names)
    assert frame_name(poses.names[0]).startswith("plant/robot0/")


def _drake_draw(quaternion_value: float, position_value: float = 0.5) -> bytes:
    """Three links encoded by Drake's own class, one quaternion and one position value chosen."""
    message = drake_lcmtypes.lcmt_viewer_draw()
    message.timestamp, message.num_links = 17, 3
    message.link_name = ["plant::a", "plant::b::c", "plant::d"]
    message.robot_num = [0, 1, 2]
    message.position = [[0.0, 1.0, 2.0], [3.0, 4.0, position_value], [6.0, 7.0, 8.0]]
    message.quaternion = [[1.0, 0.0, 0.0, 0.0], [0.0, quaternion_value, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5]]
    return bytes(message.encode())


@pytest.mark.parametrize(
    ("value", "other"),
    [(float("nan"), 0.5), (float("inf"), 0.5), (float("-inf"), 0.5), (float("inf"), float("-inf"))],
)
def test_draw_fast_path_refuses_what_is_not_finite_like_the_generic_decoder(
    value: float, other: float
) -> None:
    decoder = DrawDecoder()
    decoder.decode(_drake_draw(1.0))  # the names are known: the next draw takes the fast path
    bad = _drake_draw(value, other)
    with pytest.raises(DecodeError) as expected:
        DRAW.strict.decode(bad)
    with warnings.catch_warnings(record=True) as shown:
        for data in (bad, bytearray(bad), memoryview(bad)):
            with pytest.raises(DecodeError) as caught:
                decoder.decode(data)
            assert str(caught.value) == str(expected.value)
    assert not shown  # no numpy warning on the way


def test_draw_fast_path_takes_the_largest_finite_floats() -> None:
    largest = float(np.finfo(np.float32).max)
    decoder = DrawDecoder()
    decoder.decode(_drake_draw(1.0))
    data = _drake_draw(-largest, largest)
    with warnings.catch_warnings(record=True) as shown:
        poses = decoder.decode(data)
    assert not shown
    theirs = drake_lcmtypes.lcmt_viewer_draw.decode(data)
    assert poses.positions.tolist() == [list(p) for p in theirs.position]
    assert poses.quaternions_wxyz.tolist() == [list(q) for q in theirs.quaternion]
    assert not poses.positions.flags.owndata  # views of the one copy the decoder made
