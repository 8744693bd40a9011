"""What every bench script returns, so that `bench/all.py` can gather them into one table, and what
they share: timing (`best_of`) and a frame of link poses to draw (`frame`).

Only `viewer_bridge.scene` from the bridge: bench/load_targets.py imports this beside an older commit's
`bridge` too.
"""

from __future__ import annotations

import timeit
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from viewer_bridge.scene import LinkPoses


@dataclass
class Measure:
    """One figure of a benchmark: ours against a baseline measured in the same run, and its goal."""

    name: str
    ours: float
    baseline: float | None
    unit: str
    goal: str
    met: bool | None


def best_of(fn: Callable[[], object], repeat: int = 5, number: int = 1) -> float:
    """Seconds per call of `fn`: the minimum over `repeat` runs of `number` calls each.

    The minimum, because on a shared machine every disturbance only adds time.
    """
    return min(timeit.repeat(fn, repeat=repeat, number=number)) / number


def frame(links: int, seed: int = 0) -> LinkPoses:
    """A draw of `links` links named as Drake names them, at random poses (the same for a `seed`)."""
    rng = np.random.default_rng(seed)
    quaternions = rng.normal(size=(links, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    return LinkPoses(
        timestamp_ms=1234,
        names=tuple(f"plant::robot{i % 7}::link_{i}" for i in range(links)),
        robot_nums=(np.arange(links) % 7).astype(np.int32),
        positions=rng.normal(size=(links, 3)),
        quaternions_wxyz=quaternions,
    )
