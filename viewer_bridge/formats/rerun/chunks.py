"""Rerun archetypes -> chunks (Arrow record batches with Rerun's metadata), and how entities are named.

A chunk is one entity's rows: `static_batch` makes a static one (no timeline: a late viewer
gets it and it holds at every time), `timed_batch` one row at a message's `Stamp` on both
timelines. Entity paths are built from parts escaped by the SDK, so a link named `a b` or
`x/y` stays one part.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk

from viewer_bridge.formats.rerun.schema import RECEIVE_TIME, SIM_TIME

__all__ = ["Stamp", "entity_path", "received_batch", "static_batch", "timed_batch", "time_columns"]


@dataclass(frozen=True, slots=True)
class Stamp:
    """When a message happened: Drake's sim time and the bridge's receive time, in nanoseconds."""

    sim_ns: int
    received_ns: int

    @classmethod
    def of(cls, sim_us: int, received_us: int) -> Stamp:
        return cls(sim_us * 1000, received_us * 1000)


def entity_path(*parts: str) -> str:
    """`/a/b/c` from unescaped parts (each may hold `/`, spaces, ...); "" parts are left out."""
    return "/" + "/".join(rr.escape_entity_path_part(part) for part in parts if part)


def time_columns(stamp: Stamp, rows: int = 1) -> list[rr.TimeColumn]:
    """`rows` rows at `stamp` on the sim_time and receive_time timelines."""
    return [
        rr.TimeColumn(SIM_TIME, duration=np.full(rows, stamp.sim_ns, dtype="timedelta64[ns]")),
        rr.TimeColumn(RECEIVE_TIME, timestamp=np.full(rows, stamp.received_ns, dtype="datetime64[ns]")),
    ]


def _one_row(archetypes: Iterable[rr.AsComponents]) -> list[rr.ComponentColumn]:
    """Each archetype's components as columns of one row (the whole batch of instances in it)."""
    return [
        rr.ComponentColumn(batch.component_descriptor(), batch, lengths=[len(batch.as_arrow_array())])
        for archetype in archetypes
        for batch in archetype.as_component_batches()
    ]


def static_batch(path: str, archetypes: Iterable[rr.AsComponents]) -> pa.RecordBatch:
    """One static row of `archetypes` on the entity `path`."""
    return Chunk.from_columns(path, [], _one_row(archetypes)).to_record_batch()


def timed_batch(path: str, stamp: Stamp, archetypes: Iterable[rr.AsComponents]) -> pa.RecordBatch:
    """One row of `archetypes` on the entity `path`, at `stamp`."""
    return Chunk.from_columns(path, time_columns(stamp), _one_row(archetypes)).to_record_batch()


def received_batch(path: str, received_us: int, archetypes: Iterable[rr.AsComponents]) -> pa.RecordBatch:
    """One row of `archetypes` on the entity `path`, on the receive_time timeline alone (for a
    message that carries no simulation time)."""
    column = rr.TimeColumn(RECEIVE_TIME, timestamp=np.full(1, received_us * 1000, dtype="datetime64[ns]"))
    return Chunk.from_columns(path, [column], _one_row(archetypes)).to_record_batch()
