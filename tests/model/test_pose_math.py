"""Batched pose maths: rotations, and the world poses of parts on links, held to `Pose.compose`."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from viewer_bridge.model.pose_math import PartsOnLinks, rotation_matrix, wxyz_from_xyzw, xyzw_from_wxyz
from viewer_bridge.model.scene import Pose


def test_quaternion_orders_round_trip() -> None:
    wxyz = np.array([[0.1, 0.2, 0.3, 0.4], [1.0, 0.0, 0.0, 0.0]])
    assert xyzw_from_wxyz(wxyz).tolist() == [[0.2, 0.3, 0.4, 0.1], [0.0, 0.0, 0.0, 1.0]]
    assert wxyz_from_xyzw(xyzw_from_wxyz(wxyz)).tolist() == wxyz.tolist()


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
