"""The slow, readable builder of a draw's transforms chunk: the SDK's own `Transform3D.columns`
and `Chunk.from_columns`, which `viewer_bridge.formats.rerun.transforms` is held to (and the
bench's baseline for one batched call)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk

from viewer_bridge.formats.rerun.chunks import Stamp, time_columns
from viewer_bridge.model.scene import LinkPoses


def transforms_batch(
    path: str, poses: LinkPoses, frames: Callable[[str], str], world: str, stamp: Stamp
) -> pa.RecordBatch:
    count = len(poses.names)
    w, x, y, z = np.asarray(poses.quaternions_wxyz, dtype=np.float64).T
    columns = rr.Transform3D.columns(
        translation=np.asarray(poses.positions, dtype=np.float64),
        quaternion=np.stack([x, y, z, w], axis=1),
        child_frame=[frames(name) for name in poses.names],
        parent_frame=[world] * count,
    )
    return Chunk.from_columns(path, time_columns(stamp, count), columns).to_record_batch()
