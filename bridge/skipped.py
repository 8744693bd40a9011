"""One bad geometry never hides the rest: a geometry a target cannot write is skipped alone.

A load that names one mesh file which is not on this machine (or one a target cannot express)
must still show every other geometry. So every format that writes a scene's geometries does it
through `per_geometry`: a `SceneError` for one geometry skips that geometry only, and becomes a
`SkippedGeometry` warning that names the link, the geometry's index and the reason.

Warnings go to whoever collects them (`collecting`: the router counts them per route, `convert`
and `snapshot` print them); with no collector they are logged. A context variable carries the
collector, so that threads (a route's worker, a transport's thread) each count their own.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import TypeVar

from bridge.errors import SceneError
from bridge.scene import Geometry, Link

log = logging.getLogger("viewer_bridge")
T = TypeVar("T")


@dataclass(frozen=True, slots=True)
class SkippedGeometry:
    """A geometry left out of a target's output, and why."""

    link: str
    index: int
    reason: str

    def __str__(self) -> str:
        return f"{self.link} geometry {self.index} skipped: {self.reason}"


_collector: ContextVar[list[SkippedGeometry] | None] = ContextVar("skipped_geometries", default=None)


@contextmanager
def collecting() -> Iterator[list[SkippedGeometry]]:
    """Collect the geometries skipped in this block (in this thread) into the list it yields."""
    skipped: list[SkippedGeometry] = []
    token = _collector.set(skipped)
    try:
        yield skipped
    finally:
        _collector.reset(token)


def per_geometry(link: Link, write: Callable[[int, Geometry], T]) -> list[T]:
    """`write(index, geometry)` for each geometry of the link; one that raises `SceneError` is
    skipped with a warning. `write` must change nothing before it raises (return, then add)."""
    written = []
    for index, geometry in enumerate(link.geometries):
        try:
            written.append(write(index, geometry))
        except SceneError as error:
            _skip(SkippedGeometry(link.name, index, str(error)))
    return written


def _skip(skipped: SkippedGeometry) -> None:
    collector = _collector.get()
    if collector is None:
        log.warning("%s", skipped)
    else:
        collector.append(skipped)
