"""The tree viewer's fast settransform path against the reference (`encode(draw_request(...))`).

JSON has many spellings of one value (the fast path pads with spaces and writes every decimal),
so the fast path is held to two references: the decoded request of `draw_request` (what a
viewer reads, equal number for number), and its own bytes written the slow way, one number at a
time in Python (`fixed_width_reference`).
"""

from __future__ import annotations

import math

import numpy as np
import orjson
from hypothesis import example, given, settings
from hypothesis import strategies as st

from bridge.formats import tree_viewer as tv
from bridge.formats.drake import DrawDecoder, DrawEncoder
from bridge.lcmcodec import VIEWER2_COMMS
from bridge.scene import LinkPoses
from tests.conftest import Capture
from tests.strategies import link_poses


def reference(poses: LinkPoses, prefix: tuple[str, ...], utime: int = 0) -> bytes:
    return tv.encode(tv.draw_request(poses, prefix, utime))


def fixed_width_reference(poses: LinkPoses, prefix: tuple[str, ...], utime: int = 0) -> bytes:
    """The fast path's bytes, written the slow way: one number, one link at a time in Python,
    from the integer k = round(value * 10**8) (exact integer text, no float formatting)."""

    def number(value: float, separator: str) -> str:
        k = round(value * 10**tv.DECIMALS)
        sign = "-" if math.copysign(1.0, value) < 0 else ""  # -0.0 too, as the value's own sign
        whole, fraction = divmod(abs(k), 10**tv.DECIMALS)
        return separator + f"{sign}{whole}.".rjust(7) + f"{fraction:08d}"

    heads = [
        '{"path":' + orjson.dumps([*prefix, str(int(robot_num)), name]).decode() + ',"transform":{"translation":['
        for name, robot_num in zip(poses.names, poses.robot_nums.tolist(), strict=True)
    ]
    width = -(-max(len(head.encode()) for head in heads) // 8) * 8
    rows = []
    for index, (head, position, quaternion) in enumerate(
        zip(heads, poses.positions.tolist(), poses.quaternions_wxyz.tolist(), strict=True)
    ):
        values = [number(value, "," if place else " ") for place, value in enumerate(position)]
        values.append('],"quaternion":[')
        values += [number(value, "," if place else " ") for place, value in enumerate(quaternion)]
        end = "]}}," if index < len(heads) - 1 else "]}}"
        rows.append(" " * (width - len(head.encode())) + head + "".join(values) + end.ljust(8))
    utime = utime or poses.timestamp_ms * 1000
    text = f'{{"timestamp":{utime},"setgeometry":[],"settransform":[' + "".join(rows) + '],"delete":[]}'
    return tv.envelope(text.encode(), utime)


def assert_same_request(fast: bytes, slow: bytes) -> None:
    """Equal envelopes apart from the JSON's spelling, and equal requests."""
    fast_message, slow_message = VIEWER2_COMMS.decode(fast), VIEWER2_COMMS.decode(slow)
    assert (fast_message.utime, fast_message.format, fast_message.format_version_major) == (
        slow_message.utime,
        slow_message.format,
        slow_message.format_version_major,
    )
    assert fast_message.num_bytes == len(fast_message.data)
    assert tv.decode(fast) == tv.decode(slow) == orjson.loads(slow_message.data)


@settings(max_examples=200, deadline=None)
@given(st.lists(link_poses(max_links=8), min_size=1, max_size=4), st.sampled_from([(), ("drake",), ('a"\\', "é")]))
def test_settransform_equals_the_reference(frames: list[LinkPoses], prefix: tuple[str, ...]) -> None:
    encoder = tv.SettransformEncoder(prefix)  # one encoder for all frames: its template must follow the links
    for poses in frames:
        assert_same_request(encoder.encode(poses), reference(poses, prefix))
        assert_same_request(encoder.encode(poses, utime=7), reference(poses, prefix, 7))
        if len(poses) and np.abs(tv.settransform_values(poses)).max() < 9998.9:
            assert encoder.encode(poses, utime=7) == fixed_width_reference(poses, prefix, 7)


def test_settransform_of_real_drake_draws_through_the_decoder(drake_capture: dict[str, Capture]) -> None:
    for capture in drake_capture.values():
        poses = DrawDecoder().decode(DrawEncoder().encode(capture.poses))  # the decoder's float32 arrays
        assert poses.positions.dtype == np.dtype(np.float32)
        encoder = tv.SettransformEncoder()
        assert_same_request(encoder.encode(poses), reference(poses, tv.DEFAULT_PREFIX))
        assert encoder.encode(poses) == fixed_width_reference(poses, tv.DEFAULT_PREFIX)
        moved = LinkPoses(poses.timestamp_ms + 1, poses.names, poses.robot_nums, poses.positions * 2, poses.quaternions_wxyz)
        assert_same_request(encoder.encode(moved), reference(moved, tv.DEFAULT_PREFIX))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-9998.999999999, 9998.999999999, allow_subnormal=True), min_size=7, max_size=7))
@example([0.0] * 6 + [64.958984375])  # a tie, found by a run of this test
def test_every_number_in_the_table_range_reads_back_as_the_rounded_value(numbers: list[float]) -> None:
    poses = LinkPoses(1, ("a",), np.zeros(1, np.int32), np.array([numbers[:3]]), np.array([numbers[3:]]))
    data = tv.SettransformEncoder().encode(poses)
    assert data == fixed_width_reference(poses, tv.DEFAULT_PREFIX)
    (command,) = tv.decode(data)["settransform"]
    written = command["transform"]["translation"] + command["transform"]["quaternion"]
    assert written == [round(number * 1e8) / 1e8 for number in numbers]  # the double nearest k / 10**8
    # Half the last decimal, plus the round-off of number * 1e8 and of the double nearest k / 10**8
    # (64.958984375 is a tie: 64.95898438 is 5e-9 away as a real number, 5.000004e-9 as doubles).
    assert all(
        abs(value - number) <= 5e-9 + 4 * np.spacing(abs(number)) for value, number in zip(written, numbers, strict=True)
    )


def test_numbers_outside_the_tables_fall_back_to_orjson() -> None:
    values = [0.0, -0.0, 1e-7, 1e300, 5e-324, 123456789012345680.0, 1.0, -2.5]
    positions = np.array(values[:6], dtype=np.float64).reshape(2, 3)
    quaternions = np.array(values, dtype=np.float64).reshape(2, 4)
    poses = LinkPoses(3, ("a", 'b"\n\\'), np.array([0, -1], dtype=np.int32), positions, quaternions)
    assert tv.SettransformEncoder().encode(poses) == reference(poses, tv.DEFAULT_PREFIX)  # orjson's own bytes
    empty = LinkPoses(3, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))
    assert tv.SettransformEncoder().encode(empty) == reference(empty, tv.DEFAULT_PREFIX)
    edge = LinkPoses(3, ("a",), np.zeros(1, np.int32), np.array([[9999.0, -9999.0, 1.0]]), quaternions[:1])
    assert tv.SettransformEncoder().encode(edge) == reference(edge, tv.DEFAULT_PREFIX)  # past the tables
    huge = LinkPoses(3, ("a",), np.zeros(1, np.int32), np.array([[1e301, -1.7e308, 12345678.123]]), quaternions[:1])
    (command,) = tv.decode(tv.SettransformEncoder().encode(huge))["settransform"]
    assert command["transform"]["translation"] == [1e301, -1.7e308, 12345678.123]  # not rounded, not inf


def test_the_fixed_width_text_is_what_it_claims() -> None:
    positions = np.array([[-0.000000004, 9998.5, -12.25]])
    poses = LinkPoses(1, ("link",), np.array([2], np.int32), positions, np.array([[1.0, -0.0, 0.5, -1.0]]))
    data = VIEWER2_COMMS.decode(tv.SettransformEncoder().encode(poses)).data
    # Each number in 16 bytes: separator, sign and integer part right-aligned, point, 8 decimals.
    assert b'"translation":[     -0.00000000,  9998.50000000,   -12.25000000]' in data
    assert b'"quaternion":[      1.00000000,    -0.00000000,     0.50000000,    -1.00000000]' in data
