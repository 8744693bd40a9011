"""What every bench script returns, so that `bench/all.py` can gather them into one table."""

from __future__ import annotations

import timeit
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class Measure:
    name: str
    ours: float
    baseline: float | None
    unit: str
    goal: str
    met: bool | None


def best_of(fn: Callable[[], object], repeat: int = 5, number: int = 1) -> float:
    """Seconds per call of `fn`: the minimum over `repeat` runs of `number` calls each."""
    return min(timeit.repeat(fn, repeat=repeat, number=number)) / number
