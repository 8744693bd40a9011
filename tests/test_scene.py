"""The neutral scene model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from viewer_bridge.scene import LinkPoses, PartsOnLinks, Pose, frame_name, rotation_matrix


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


def test_rotation_about_z() -> None:
    half = np.pi / 4
    matrix = rotation_matrix(np.array([np.cos(half), 0.0, 0.0, np.sin(half)]))  # w first: 90 deg about z
    assert matrix @ np.array([1.0, 0.0, 0.0]) == pytest.approx([0.0, 1.0, 0.0])


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(0, 12))
def test_parts_on_links_match_pose_compose(seed: int, parts: int, links: int) -> None:
    """All parts' world poses at once agree with composing each pair of poses by itself."""
    rng = np.random.default_rng(seed)

    def unit(rows: int) -> np.ndarray:  # type: ignore[type-arg]
        values = rng.normal(size=(rows, 4))
        return values / np.linalg.norm(values, axis=1, keepdims=True)

    part_positions, part_wxyz = rng.normal(size=(parts, 3)), unit(parts)
    link_positions = rng.normal(size=(links, 3)).astype(">f4")  # as a draw's views arrive
    link_wxyz = unit(links).astype(">f4")
    rows = rng.integers(0, links + 1, size=parts)  # row `links` is no link: the identity
    world = PartsOnLinks(part_positions, part_wxyz).world_rows(link_positions, link_wxyz, rows)
    for part, row in enumerate(rows):
        link = Pose()
        if row < links:
            w, x, y, z = link_wxyz[row].tolist()
            link = Pose(tuple(link_positions[row].tolist()), (w, x, y, z))  # type: ignore[arg-type]
        expected = link.compose(Pose(tuple(part_positions[part]), tuple(part_wxyz[part])))  # type: ignore[arg-type]
        np.testing.assert_allclose(world[part, :3], expected.position, atol=1e-6)
        np.testing.assert_allclose(world[part, 3:], expected.quaternion_xyzw, atol=1e-6)


def test_link_poses_of_arrays_sets_every_field_as_the_constructor_does() -> None:
    arrays = (np.zeros(2, np.int32), np.ones((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1)))
    fast, slow = LinkPoses.of_arrays(7, ("a", "b"), *arrays), LinkPoses(7, ("a", "b"), *arrays)
    for field in dataclasses.fields(LinkPoses):
        assert getattr(fast, field.name) is getattr(slow, field.name), field.name
    assert fast.row_of("b") == 1 and fast == slow
