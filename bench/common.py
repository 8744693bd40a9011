"""What every benchmark script shares: a measure row and a timer."""

from __future__ import annotations

import timeit
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class Measure:
    """One figure of a benchmark: ours against a baseline timed in the same run, and its goal."""

    name: str
    ours: float
    baseline: float | None
    unit: str
    goal: str
    met: bool | None


def best_of(fn: Callable[[], object], repeat: int, number: int) -> float:
    """Seconds per call of `fn`: the best of `repeat` runs of `number` calls.

    The minimum, because on a shared machine every disturbance only adds time.
    """
    return min(timeit.repeat(fn, repeat=repeat, number=number)) / number
