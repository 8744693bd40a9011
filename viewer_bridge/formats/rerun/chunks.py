"""Rerun archetypes -> chunks (the SDK's `Chunk`, as a `Chunks` message), and how entities are named.

A chunk is one entity's rows: `static_chunk` makes a static one (no timeline: a late viewer
gets it and it holds at every time), `timed_chunk` one row at a message's `Stamp` on both
timelines. Entity paths are built from parts escaped by the SDK, so a link named `a b` or
`x/y` stays one part.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import rerun as rr
from rerun.chunk import Chunk

from viewer_bridge.formats.rerun.schema import RECEIVE_TIME, SIM_TIME, Chunks


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


def _one_row(path: str, times: list[rr.TimeColumn], archetypes: Iterable[rr.AsComponents]) -> Chunks:
    """A chunk of one row on `path` at `times`: each archetype's components as columns of that
    row (the whole batch of instances in it)."""
    columns, size = [], 0
    for archetype in archetypes:
        for batch in archetype.as_component_batches():
            values = batch.as_arrow_array()
            columns.append(rr.ComponentColumn(batch.component_descriptor(), batch, lengths=[len(values)]))
            size += values.nbytes
    return Chunks([Chunk.from_columns(path, times, columns)], size)


def static_chunk(path: str, archetypes: Iterable[rr.AsComponents]) -> Chunks:
    """One static row of `archetypes` on the entity `path`."""
    return _one_row(path, [], archetypes)


def timed_chunk(path: str, stamp: Stamp, archetypes: Iterable[rr.AsComponents]) -> Chunks:
    """One row of `archetypes` on the entity `path`, at `stamp`."""
    return _one_row(path, time_columns(stamp), archetypes)


def received_chunk(path: str, received_us: int, archetypes: Iterable[rr.AsComponents]) -> Chunks:
    """One row of `archetypes` on the entity `path`, on the receive_time timeline alone (for a
    message that carries no simulation time)."""
    column = rr.TimeColumn(RECEIVE_TIME, timestamp=np.full(1, received_us * 1000, dtype="datetime64[ns]"))
    return _one_row(path, [column], archetypes)
