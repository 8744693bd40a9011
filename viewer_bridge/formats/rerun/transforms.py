"""A draw as one Rerun chunk: every link's frame at the draw's time, in one batch.

Rerun's transform frames (as ROS's /tf) let one entity hold the transforms of many frames:
each row a `Transform3D` from its `child_frame` (a link's frame) to `parent_frame` (the
world). So a draw of N links is one chunk of N rows on the entity `<root>/transforms`, all at
the draw's sim time and receive time, built here straight from the draw's arrays: the frame
names are Arrow arrays made once per set of link names, the rest is a few array copies. The
slow, readable builder of the same batch (`Transform3D.columns`, `Chunk.from_columns`) is
`tests/formats/rerun/oracle.py`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk

from viewer_bridge.formats.rerun.chunks import Stamp, time_columns
from viewer_bridge.model.scene import LinkPoses

__all__ = ["TransformsEncoder"]

_CONTROL = b"rerun.controls.RowId"  # the SDK makes row and chunk ids for batches without them


def _schema(path: str) -> pa.Schema:
    """The schema of a transforms chunk on `path`, as the SDK writes it, less its ids."""
    sample = Chunk.from_columns(
        path,
        time_columns(Stamp(0, 0)),
        rr.Transform3D.columns(translation=[[0, 0, 0]], quaternion=[[0, 0, 0, 1]], child_frame=["a"], parent_frame=["b"]),
    ).to_record_batch().schema
    schema = sample.remove(sample.get_field_index(_CONTROL.decode()))
    metadata = {key: value for key, value in (schema.metadata or {}).items() if key != b"rerun:id"}
    return schema.with_metadata(metadata)


_TIMESTAMP = pa.timestamp("ns")
_DURATION = pa.duration("ns")


def _repeated(kind: pa.DataType, value: int, count: int) -> pa.Array:
    """`count` times one time value, straight from an int64 buffer (no conversion)."""
    return pa.Array.from_buffers(kind, count, [None, pa.py_buffer(np.full(count, value, dtype=np.int64))])


class TransformsEncoder:
    """Link poses -> one record batch of Transform3D rows, world -> every link.

    One encoder per stream (its entity and frame names); one thread at a time.
    """

    def __init__(self, path: str, frames: Callable[[str], str], world_frame: str) -> None:
        self.path = path
        self.frames = frames
        self.world_frame = world_frame
        self._schema = _schema(path)
        self._names: tuple[str, ...] = ()
        self._frame_columns: tuple[pa.Array, pa.Array] = self._frame_arrays(())

    def _frame_arrays(self, names: tuple[str, ...]) -> tuple[pa.Array, pa.Array]:
        offsets = pa.array(np.arange(len(names) + 1, dtype=np.int32))
        children = pa.ListArray.from_arrays(offsets, pa.array([self.frames(name) for name in names], pa.utf8()))
        parents = pa.ListArray.from_arrays(offsets, pa.array([self.world_frame] * len(names), pa.utf8()))
        self._offsets = offsets
        return children, parents

    def encode(self, poses: LinkPoses, stamp: Stamp) -> pa.RecordBatch:
        if poses.names is not self._names and poses.names != self._names:  # one tuple while they repeat
            self._frame_columns = self._frame_arrays(poses.names)
        self._names = poses.names
        count = len(poses.names)
        children, parents = self._frame_columns
        xyzw = np.empty((count, 4), dtype=np.float32)
        xyzw[:, :3] = poses.quaternions_wxyz[:, 1:]
        xyzw[:, 3] = poses.quaternions_wxyz[:, 0]
        columns = {
            "receive_time": _repeated(_TIMESTAMP, stamp.received_ns, count),
            "sim_time": _repeated(_DURATION, stamp.sim_ns, count),
            "Transform3D:child_frame": children,
            "Transform3D:parent_frame": parents,
            "Transform3D:quaternion": self._rows(xyzw, "Transform3D:quaternion"),
            "Transform3D:translation": self._rows(np.asarray(poses.positions, dtype=np.float32), "Transform3D:translation"),
        }
        return pa.RecordBatch.from_arrays([columns[name] for name in self._schema.names], schema=self._schema)

    def _rows(self, values: npt.NDArray[np.float32], column: str) -> pa.Array:
        """N x width floats as N rows of one fixed-size list each, of the column's exact type (a
        nullable float where the schema says not null would be cast: a copy per column)."""
        kind = self._schema.field(column).type
        flat = pa.array(np.ascontiguousarray(values).reshape(-1))
        return pa.ListArray.from_arrays(
            self._offsets, pa.FixedSizeListArray.from_arrays(flat, type=kind.value_type), type=kind
        )
