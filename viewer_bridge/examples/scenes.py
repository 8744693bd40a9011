"""A small two-link scene and its draws, and contact results of every kind, built without Drake:
what the tests and the benchmarks publish by hand."""

from __future__ import annotations

import numpy as np

from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.model.contact import (
    ContactBody,
    ContactResults,
    ContactSurface,
    HydroelasticContact,
    PointContacts,
)
from viewer_bridge.model.scene import Box, Geometry, Link, LinkPoses, Pose, Scene, Sphere


def small_scene() -> Scene:
    return Scene(
        (
            Link("plant::robot::base", 1, (Geometry(Box((0.1, 0.2, 0.3))),)),
            Link("plant::robot::tip", 1, (Geometry(Sphere(0.05), Pose((0, 0, 0.1))),)),
        )
    )


def draw_of(scene: Scene, seconds: float) -> bytes:
    names = tuple(link.name for link in scene.links)
    positions = np.array([[0.0, 0.0, seconds], [0.5, 0.0, seconds]])
    poses = LinkPoses(
        int(seconds * 1000), names, np.ones(2, np.int32), positions, np.tile([1.0, 0, 0, 0], (2, 1))
    )
    return DrawEncoder().encode(poses)


def demo_contact_results(
    point_count: int = 4, grid: tuple[int, int] = (6, 4), timestamp_us: int = 0
) -> ContactResults:
    """Point contacts on a ring around the origin, and one hydroelastic surface: a `grid` of
    rows x columns cells (2 triangles each) 0.2 m wide beside them, paraboloid pressure."""
    angles = np.linspace(0.0, 2 * np.pi, point_count, endpoint=False)
    points = np.stack((0.3 * np.cos(angles), 0.3 * np.sin(angles), np.zeros(point_count)), axis=1)
    forces = np.stack((0.5 * np.sin(angles), np.zeros(point_count), 5.0 + np.cos(angles)), axis=1)
    normals = np.tile([0.0, 0.0, 1.0], (point_count, 1))
    pairs = tuple(("world", f"box{index}") for index in range(point_count))
    rows, columns = grid
    u, v = np.meshgrid(np.linspace(-0.1, 0.1, columns + 1), np.linspace(-0.1, 0.1, rows + 1))
    vertices = np.stack((u.ravel() + 0.6, v.ravel(), np.zeros(u.size)), axis=1)
    corner = (np.arange(rows)[:, None] * (columns + 1) + np.arange(columns)[None, :]).ravel()
    right, up = corner + 1, corner + columns + 1
    triangles = np.concatenate(
        (np.stack((corner, right, up + 1), axis=1), np.stack((corner, up + 1, up), axis=1))
    ).astype(np.int64)
    pressure = 1e5 * np.clip(1.0 - (u.ravel() ** 2 + v.ravel() ** 2) / 0.02, 0.0, None)
    surface = ContactSurface(vertices, pressure, triangles)
    contact = HydroelasticContact(
        ContactBody("sphere", "DefaultModelInstance", "sphere"),
        ContactBody("world", "WorldModelInstance", "ground"),
        np.array([0.6, 0.0, 0.0]),
        np.array([0.0, 0.5, 9.8]),
        np.array([0.2, -0.1, 0.05]),
        surface,
    )
    return ContactResults(timestamp_us, PointContacts(pairs, points, forces, normals), (contact,))
