"""One bad part never hides the rest: a geometry a target cannot write, or one image of a camera's
array that does not decode, is skipped alone.

A load that names one mesh file which is not on this machine (or one a target cannot express)
must still show every other geometry. So every format that writes a scene's geometries does it
through `per_geometry`: a `SceneError` for one geometry skips that geometry only, and becomes a
`SkippedGeometry` warning that names the link, the geometry's index and the reason.

A part of a message that is broken rather than unwritable (an image whose bytes do not decode:
`viewer_bridge.translators.drake_image`) goes through `part_failed`: the collector gets its error, which
the router counts as an error of the route (by the error's type), and the other parts go out.

Warnings and errors go to whoever collects them (`collecting`: the router counts them per route,
`convert` and `snapshot` print them); with no collector they are logged. A context variable carries the
collector, so that threads (a route's worker, a transport's thread) each count their own
(`thread_collector`: the router's, one list a thread for all its messages).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import TypeVar

from viewer_bridge.errors import BridgeError, SceneError
from viewer_bridge.model.scene import Geometry, Link

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


Skipped = SkippedGeometry | BridgeError  # a geometry left out (a warning), a part that failed (an error)
_collector: ContextVar[list[Skipped] | None] = ContextVar("skipped_geometries", default=None)


@contextmanager
def collecting() -> Iterator[list[Skipped]]:
    """Collect the parts skipped in this block (in this thread) into the list it yields."""
    skipped: list[Skipped] = []
    token = _collector.set(skipped)
    try:
        yield skipped
    finally:
        _collector.reset(token)


# The list this thread (or `collecting` block) collects into, or None before `thread_collector`
# set one: a C call, for the router's once-a-message ask.
current_collector = _collector.get


def thread_collector() -> list[Skipped]:
    """The list this thread collects skipped parts into, set for good on the first ask.

    What the router's threads use, a list each, emptied before every translation and read after
    it: `collecting` per message would cost more than a small translation (a generator and a
    context variable set and reset). Inside a `collecting` block, that block's list."""
    skipped = _collector.get()
    if skipped is None:
        skipped = []
        _collector.set(skipped)
    return skipped


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


def part_failed(error: BridgeError) -> None:
    """One part of a message that cannot be translated: the caller goes on with the others."""
    _skip(error)


def _skip(skipped: Skipped) -> None:
    collector = _collector.get()
    if collector is None:
        log.warning("%s", skipped)
    else:
        collector.append(skipped)
