"""A scene as tree viewer requests: every Drake shape out as setgeometry, and the fast
settransform path against the references (`oracle.reference`, `encode(draw_request(...))`).

JSON has many spellings of one value (the fast path pads with spaces and writes every decimal),
so the fast path is held to two references: the decoded request of `draw_request` (what a
viewer reads, equal number for number), and its own bytes written the slow way, one number at a
time in Python (`oracle.fixed_width_reference`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import orjson
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tests.conftest import Capture
from tests.formats import oracle
from tests.formats.oracle import close
from tests.formats.tree_viewer.oracle import fixed_width_reference, reference, to_decimals
from tests.strategies import link_poses
from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.tree_viewer.envelope import decode, encode
from viewer_bridge.formats.tree_viewer.requests import (
    DEFAULT_PREFIX,
    SettransformEncoder,
    load_requests,
    settransform_values,
)
from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS
from viewer_bridge.model.scene import LinkPoses

ROLES = ["ILLUSTRATION", "PROXIMITY"]


@pytest.mark.parametrize("role", ROLES)
def test_every_drake_shape_becomes_setgeometry(drake_capture: dict[str, Capture], role: str) -> None:
    capture = drake_capture[role]
    delete, load = (decode(encode(request)) for request in load_requests(capture.scene))
    assert delete["delete"] == [{"path": ["drake"]}] and delete["setgeometry"] == []
    commands = iter(load["setgeometry"])
    for raw_link in capture.load.link:
        for index, geometry in enumerate(raw_link.geom):
            command = next(commands)
            assert command["path"] == ["drake", str(raw_link.robot_num), raw_link.name, str(index)]
            shape, data = command["geometry"], geometry.float_data
            assert close(shape["transform"]["quaternion"], geometry.quaternion)  # w first, as Drake's
            assert close(shape["transform"]["translation"], geometry.position)
            assert close(shape["color"], geometry.color)
            kind = oracle.mesh_kind(geometry)
            expected: dict[str, Any] = {
                oracle.BOX: {"type": "box", "lengths": data},
                oracle.SPHERE: {"type": "sphere", "radius": data[0] if data else None},
                oracle.CYLINDER: {"type": "cylinder", "radius": data[0], "length": data[-1]},
                oracle.CAPSULE: {"type": "capsule", "radius": data[0], "length": data[-1]},
                oracle.ELLIPSOID: {"type": "ellipsoid", "radii": data},
            }.get(geometry.type, {})
            if kind == "file":
                expected = {"type": "mesh_file", "filename": geometry.string_data, "scale": data}
            elif kind == "array":
                vertices, triangles = oracle.mesh_array(geometry)
                expected = {"type": "mesh_data", "vertices": vertices.tolist(), "faces": triangles.tolist()}
            elif kind == "memory":  # read with trimesh: the tetrahedron, scaled
                expected = {"type": "mesh_data", "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]}
            assert shape["type"] == expected.pop("type")
            for key, value in expected.items():
                assert close(shape[key], value) if key != "filename" else shape[key] == value, key
    assert next(commands, None) is None
    settransform = {tuple(c["path"]): c["transform"] for c in load["settransform"]}
    for index, name in enumerate(capture.poses.names):
        transform = settransform[("drake", str(capture.poses.robot_nums[index]), name)]
        assert transform["quaternion"] == to_decimals(capture.poses.quaternions_wxyz[index])
        assert transform["translation"] == to_decimals(capture.poses.positions[index])


def assert_same_request(fast: bytes, slow: bytes) -> None:
    """Equal envelopes apart from the JSON's spelling, and equal requests."""
    fast_message, slow_message = VIEWER2_COMMS.decode(fast), VIEWER2_COMMS.decode(slow)
    assert (fast_message.utime, fast_message.format, fast_message.format_version_major) == (
        slow_message.utime,
        slow_message.format,
        slow_message.format_version_major,
    )
    assert fast_message.num_bytes == len(fast_message.data)
    assert decode(fast) == decode(slow) == orjson.loads(slow_message.data)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(link_poses(max_links=8), min_size=1, max_size=4),
    st.sampled_from([(), ("drake",), ('a"\\', "é")]),
)
def test_settransform_equals_the_reference(frames: list[LinkPoses], prefix: tuple[str, ...]) -> None:
    encoder = SettransformEncoder(prefix)  # one encoder for all frames: its template must follow the links
    for poses in frames:
        assert_same_request(encoder.encode(poses), reference(poses, prefix))
        assert_same_request(encoder.encode(poses, utime=7), reference(poses, prefix, 7))
        if len(poses) and np.abs(settransform_values(poses)).max() < 9998.9:
            assert encoder.encode(poses, utime=7) == fixed_width_reference(poses, prefix, 7)


def test_settransform_of_real_drake_draws_through_the_decoder(drake_capture: dict[str, Capture]) -> None:
    for capture in drake_capture.values():
        poses = DrawDecoder().decode(DrawEncoder().encode(capture.poses))  # the decoder's float32 arrays
        assert poses.positions.dtype == np.dtype(np.float32)
        encoder = SettransformEncoder()
        assert_same_request(encoder.encode(poses), reference(poses, DEFAULT_PREFIX))
        assert encoder.encode(poses) == fixed_width_reference(poses, DEFAULT_PREFIX)
        moved = LinkPoses(
            poses.timestamp_ms + 1, poses.names, poses.robot_nums, poses.positions * 2, poses.quaternions_wxyz
        )
        assert_same_request(encoder.encode(moved), reference(moved, DEFAULT_PREFIX))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(-9998.999999999, 9998.999999999, allow_subnormal=True), min_size=7, max_size=7))
@example([0.0] * 6 + [64.958984375])  # a tie, found by a run of this test
def test_every_number_in_the_table_range_reads_back_as_the_rounded_value(numbers: list[float]) -> None:
    poses = LinkPoses(1, ("a",), np.zeros(1, np.int32), np.array([numbers[:3]]), np.array([numbers[3:]]))
    data = SettransformEncoder().encode(poses)
    assert data == fixed_width_reference(poses, DEFAULT_PREFIX)
    (command,) = decode(data)["settransform"]
    written = command["transform"]["translation"] + command["transform"]["quaternion"]
    assert written == [round(number * 1e8) / 1e8 for number in numbers]  # the double nearest k / 10**8
    # Half the last decimal, plus the round-off of number * 1e8 and of the double nearest k / 10**8
    # (64.958984375 is a tie: 64.95898438 is 5e-9 away as a real number, 5.000004e-9 as doubles).
    assert all(
        abs(value - number) <= 5e-9 + 4 * np.spacing(abs(number))
        for value, number in zip(written, numbers, strict=True)
    )


def test_numbers_outside_the_tables_fall_back_to_orjson() -> None:
    values = [0.0, -0.0, 1e-7, 1e300, 5e-324, 123456789012345680.0, 1.0, -2.5]
    positions = np.array(values[:6], dtype=np.float64).reshape(2, 3)
    quaternions = np.array(values, dtype=np.float64).reshape(2, 4)
    poses = LinkPoses(3, ("a", 'b"\n\\'), np.array([0, -1], dtype=np.int32), positions, quaternions)
    assert SettransformEncoder().encode(poses) == reference(poses, DEFAULT_PREFIX)  # orjson's own bytes
    empty = LinkPoses(3, (), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))
    assert SettransformEncoder().encode(empty) == reference(empty, DEFAULT_PREFIX)
    edge = LinkPoses(3, ("a",), np.zeros(1, np.int32), np.array([[9999.0, -9999.0, 1.0]]), quaternions[:1])
    assert SettransformEncoder().encode(edge) == reference(edge, DEFAULT_PREFIX)  # past the tables
    huge = LinkPoses(
        3, ("a",), np.zeros(1, np.int32), np.array([[1e301, -1.7e308, 12345678.123]]), quaternions[:1]
    )
    (command,) = decode(SettransformEncoder().encode(huge))["settransform"]
    assert command["transform"]["translation"] == [1e301, -1.7e308, 12345678.123]  # not rounded, not inf


def test_the_fixed_width_text_is_what_it_claims() -> None:
    positions = np.array([[-0.000000004, 9998.5, -12.25]])
    poses = LinkPoses(1, ("link",), np.array([2], np.int32), positions, np.array([[1.0, -0.0, 0.5, -1.0]]))
    data = VIEWER2_COMMS.decode(SettransformEncoder().encode(poses)).data
    # Each number in 16 bytes: separator, sign and integer part right-aligned, point, 8 decimals.
    assert b'"translation":[     -0.00000000,  9998.50000000,   -12.25000000]' in data
    assert b'"quaternion":[      1.00000000,    -0.00000000,     0.50000000,    -1.00000000]' in data
