"""What every bench script returns, so that `bench/all.py` can gather them into one table, what it
is asked for (`Size`), and what they share: timing (`best_of`), a frame of link poses to draw
(`frame`) and the CPU time of a process with its children (`tree_cpu_seconds`).

Only `viewer_bridge.model.scene` from the bridge: bench/load_targets.py imports this beside an older commit's
`bridge` too.
"""

from __future__ import annotations

import enum
import os
import time
import timeit
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np

from viewer_bridge.model.scene import LinkPoses


@dataclass
class Measure:
    """One figure of a benchmark: ours against a baseline measured in the same run, and its goal."""

    name: str
    ours: float
    baseline: float | None
    unit: str
    goal: str
    met: bool | None


T = TypeVar("T")


class Size(enum.Enum):
    """How much a bench script's `measures(size)` measures.

    FULL gives the figures of the table; QUICK fewer rounds, and may leave out the slowest rows;
    SMOKE runs every row of FULL at sizes so small that it takes seconds: its figures mean
    nothing, but every path a row measures still runs (`bench/all.py --smoke`, which the test
    suite runs so that no bench rots unseen).
    """

    FULL = "full"
    QUICK = "quick"
    SMOKE = "smoke"

    def pick(self, full: T, quick: T, smoke: T) -> T:
        """This size's value of a parameter, given its value at each size."""
        return {Size.FULL: full, Size.QUICK: quick, Size.SMOKE: smoke}[self]

    @property
    def every_row(self) -> bool:
        """Whether the rows QUICK leaves out are measured (FULL and SMOKE)."""
        return self is not Size.QUICK


def settle(done: Callable[[], bool], at_most: float) -> bool:
    """A settling wait that ends once there is nothing left to wait for: until `done()`, at most
    `at_most` seconds (checked every 20 ms); whether `done()` came."""
    deadline = time.monotonic() + at_most
    while not done():
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.02)
    return True


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


def machine_busy_seconds() -> float:
    """CPU seconds the whole machine has been busy so far, every core summed (/proc/stat's first
    line: all but idle and iowait): processes, and the kernel's interrupt and softirq time that no
    process's own CPU time holds (moving packets over loopback, for one)."""
    user, nice, system, idle, iowait, irq, softirq, steal = (int(f) for f in Path("/proc/stat").read_text().split()[1:9])
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def tree_cpu_seconds(pid: int) -> float:
    """User + system CPU seconds so far of process `pid` and every live descendant of it (its worker
    processes), from /proc/PID/stat (fields 14 and 15): the difference of two calls is what the
    tree spent between them, as long as no process of it ended in between."""
    parents: dict[int, int] = {}
    spent: dict[int, float] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:  # it ended meanwhile
            continue
        parents[int(entry.name)] = int(fields[1])
        spent[int(entry.name)] = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    tree, grown = {pid}, True
    while grown:
        more = {child for child, parent in parents.items() if parent in tree} - tree
        tree |= more
        grown = bool(more)
    return sum(spent.get(member, 0.0) for member in tree)


def iiwa_status_bytes(joints: int = 7) -> bytes:
    """An lcmt_iiwa_status of `joints` joints, as pydrake's class encodes it: the benches' small message."""
    import drake

    message = drake.lcmt_iiwa_status()
    message.num_joints = joints
    for field in message.__slots__[2:]:
        setattr(message, field, [0.1 * joint for joint in range(joints)])
    return message.encode()  # type: ignore[no-any-return]
