"""A small two-link scene and its draws: what the router and translator tests publish by hand."""

from __future__ import annotations

import numpy as np

from bridge.formats.drake.draw import DrawEncoder
from bridge.scene import Box, Geometry, Link, LinkPoses, Pose, Scene, Sphere


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
