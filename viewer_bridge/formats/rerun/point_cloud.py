"""Point clouds and DRAKE_DRAW_FRAMES as Rerun archetypes: `Points3D` with the cloud's colours, in
its frame; the frames of a draw as one `Arrows3D` of red x, green y and blue z axes.

A cloud in Drake's `world` is drawn in `world` (the 3D view's root frame the Drake translators
hang links off); any other frame is a link frame as the scene names it (`plant/iiwa/iiwa_link_7`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from viewer_bridge.formats.ros.message_types import WORLD
from viewer_bridge.model.scene import LinkPoses, StampedPointCloud

_AXIS_COLORS = np.array([[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]], dtype=np.uint8)


def cloud_archetypes(stamped: StampedPointCloud, world: str) -> list[Any]:
    """The cloud's frame and its points (coloured when the cloud has colours)."""
    cloud = stamped.cloud
    frame = world if stamped.frame in ("", WORLD) else stamped.frame
    return [rr.CoordinateFrame(frame), rr.Points3D(cloud.points, colors=cloud.colors)]


def frame_arrows(poses: LinkPoses, length: float, world: str) -> list[Any]:
    """Every frame of a draw as three arrows from its origin along its axes, `length` long."""
    w, x, y, z = np.asarray(poses.quaternions_wxyz, dtype=np.float64).T
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    # The columns of each frame's rotation matrix: its x, y and z axes in the world.
    axes = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=1),
            np.stack([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)], axis=1),
            np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1),
        ],
        axis=1,
    )  # N x 3 axes x 3
    origins = np.repeat(np.asarray(poses.positions, dtype=np.float64), 3, axis=0)
    return [
        rr.CoordinateFrame(world),
        rr.Arrows3D(
            origins=origins,
            vectors=axes.reshape(-1, 3) * length,
            colors=np.tile(_AXIS_COLORS, (len(poses), 1)),
        ),
    ]
