"""A draw as one Rerun chunk: every link's frame at the draw's time, in one batch.

Rerun's transform frames (as ROS's /tf) let one entity hold the transforms of many frames:
each row a `Transform3D` from its `child_frame` (a link's frame) to `parent_frame` (the
world). So a draw of N links is one chunk of N rows on the entity `<root>/transforms`, all at
the draw's sim time and receive time, built here straight from the draw's arrays into the
SDK's `Chunk.from_columns`: the frame names are Arrow arrays made once per set of link names,
the rest is a few array copies (no `Transform3D` of Python values, no record batch for the SDK
to read back). The slow, readable builder of the same chunk (`Transform3D.columns`) is
`tests/formats/rerun/oracle.py`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk

from viewer_bridge.formats.rerun.chunks import Stamp
from viewer_bridge.formats.rerun.schema import RECEIVE_TIME, SIM_TIME, Chunks
from viewer_bridge.model.scene import LinkPoses

_TIMESTAMP = pa.timestamp("ns")
_DURATION = pa.duration("ns")


class _Rows(rr.ComponentColumn):
    """A component column from its Arrow list array (a row per draw link: one instance in each),
    made here with offsets made once per set of links: the SDK's own column would partition its
    values again each time `Chunk.from_columns` reads it."""

    def __init__(self, descriptor: rr.ComponentDescriptor, rows: pa.ListArray) -> None:
        self.descriptor = descriptor
        self.rows = rows

    def as_arrow_array(self) -> pa.Array:
        return self.rows


class _Times:
    """`count` times one time value as the SDK's `TimeColumnLike`, straight from an int64 buffer."""

    __slots__ = ("name", "array")

    def __init__(self, name: str, kind: pa.DataType, value: int, count: int) -> None:
        self.name = name
        self.array = pa.Array.from_buffers(
            kind, count, [None, pa.py_buffer(np.full(count, value, dtype=np.int64))]
        )

    def timeline_name(self) -> str:
        return self.name

    def as_arrow_array(self) -> pa.Array:
        return self.array


def _sample_columns() -> dict[str, rr.ComponentColumn]:
    """A one-row Transform3D's columns by component: their descriptors and value types, as the SDK makes them."""
    columns = rr.Transform3D.columns(
        translation=[[0, 0, 0]], quaternion=[[0, 0, 0, 1]], child_frame=["a"], parent_frame=["b"]
    )
    return {column.component_descriptor().component: column for column in columns}


class TransformsEncoder:
    """Link poses -> one chunk of Transform3D rows, world -> every link.

    One encoder per stream (its entity and frame names); one thread at a time.
    """

    def __init__(self, path: str, frames: Callable[[str], str], world_frame: str) -> None:
        self.path = path
        self.frames = frames
        self.world_frame = world_frame
        sample = _sample_columns()
        self._descriptors = {name: column.component_descriptor() for name, column in sample.items()}
        self._kinds = {name: column.component_batch.as_arrow_array().type for name, column in sample.items()}
        self._names: tuple[str, ...] | None = None
        self._offsets = pa.array(np.zeros(1, dtype=np.int32))
        self._frame_columns: list[rr.ComponentColumn] = []
        self._frames_size = 0

    def _frame_arrays(self, names: tuple[str, ...]) -> None:
        """What repeats while the link names do: the offsets of one instance per row, the child and
        parent frame columns."""
        self._offsets = pa.array(np.arange(len(names) + 1, dtype=np.int32))
        children = pa.array([self.frames(name) for name in names], pa.utf8())
        parents = pa.array([self.world_frame] * len(names), pa.utf8())
        self._frame_columns = [
            self._column("Transform3D:child_frame", children),
            self._column("Transform3D:parent_frame", parents),
        ]
        self._frames_size = children.nbytes + parents.nbytes  # once: nbytes walks the buffers

    def _column(self, component: str, values: pa.Array) -> rr.ComponentColumn:
        return _Rows(self._descriptors[component], pa.ListArray.from_arrays(self._offsets, values))

    def encode(self, poses: LinkPoses, stamp: Stamp) -> Chunks:
        if poses.names is not self._names and poses.names != self._names:  # one tuple while they repeat
            self._frame_arrays(poses.names)
        self._names = poses.names
        count = len(poses.names)
        xyzw = np.empty((count, 4), dtype=np.float32)
        xyzw[:, :3] = poses.quaternions_wxyz[:, 1:]
        xyzw[:, 3] = poses.quaternions_wxyz[:, 0]
        translations = self._fixed_rows(
            "Transform3D:translation", np.asarray(poses.positions, dtype=np.float32)
        )
        quaternions = self._fixed_rows("Transform3D:quaternion", xyzw)
        chunk = Chunk.from_columns(
            self.path,
            [
                _Times(SIM_TIME, _DURATION, stamp.sim_ns, count),
                _Times(RECEIVE_TIME, _TIMESTAMP, stamp.received_ns, count),
            ],
            [
                self._column("Transform3D:translation", translations),
                self._column("Transform3D:quaternion", quaternions),
                *self._frame_columns,
            ],
        )
        return Chunks([chunk], count * (3 + 4) * 4 + self._frames_size)  # float32 xyz and xyzw

    def _fixed_rows(self, component: str, values: npt.NDArray[np.float32]) -> pa.Array:
        """N x width floats as N fixed-size lists of the component's exact type (a nullable float
        where the SDK's type says not null would be cast: a copy per column)."""
        kind = self._kinds[component]
        flat = pa.array(np.ascontiguousarray(values).reshape(-1))
        return pa.FixedSizeListArray.from_arrays(flat, type=kind)
