"""The neutral scene model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from viewer_bridge.model.scene import LinkPoses, Pose, frame_name


def test_frame_names_follow_the_field_convention() -> None:
    assert frame_name("plant::iiwa::iiwa_link_0") == "plant/iiwa/iiwa_link_0"
    assert frame_name("world") == "world"


def test_quaternion_orders() -> None:
    pose = Pose((1.0, 2.0, 3.0), (0.1, 0.2, 0.3, 0.4))
    assert pose.quaternion_xyzw == (0.2, 0.3, 0.4, 0.1)


unit = st.floats(-1, 1, allow_nan=False)


@given(
    st.tuples(unit, unit, unit, unit).filter(lambda q: sum(v * v for v in q) > 0.1),
    st.tuples(unit, unit, unit),
    st.tuples(unit, unit, unit, unit).filter(lambda q: sum(v * v for v in q) > 0.1),
    st.tuples(unit, unit, unit),
)
def test_compose_matches_matrix_product(
    q1: tuple[float, ...], p1: tuple[float, ...], q2: tuple[float, ...], p2: tuple[float, ...]
) -> None:
    def unit_quaternion(q: tuple[float, ...]) -> tuple[float, float, float, float]:
        n = float(np.linalg.norm(q))
        return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)

    a = Pose((p1[0], p1[1], p1[2]), unit_quaternion(q1))
    b = Pose((p2[0], p2[1], p2[2]), unit_quaternion(q2))
    assert a.compose(b).matrix() == pytest.approx(a.matrix() @ b.matrix(), abs=1e-9)


def test_link_poses_of_arrays_sets_every_field_as_the_constructor_does() -> None:
    arrays = (np.zeros(2, np.int32), np.ones((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1)))
    fast, slow = LinkPoses.of_arrays(7, ("a", "b"), *arrays), LinkPoses(7, ("a", "b"), *arrays)
    for field in dataclasses.fields(LinkPoses):
        assert getattr(fast, field.name) is getattr(slow, field.name), field.name
    assert fast.row_of("b") == 1 and fast == slow
