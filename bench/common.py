"""What every bench script returns, so that `bench/all.py` can gather them into one table, what it
is asked for (`Size`), and what they share: timing (`best_of`), a publisher's pace (`paced`), a
frame of link poses to draw (`frame`) and the CPU time of a process with its children
(`tree_cpu_seconds`).

Only `viewer_bridge.model.scene` from the bridge: bench/load_targets.py imports this beside an older commit's
`bridge` too.
"""

from __future__ import annotations

import enum
import multiprocessing
import os
import time
import timeit
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

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


def paced(publish: Any, count: int, rate_hz: float, seconds: float) -> int:
    """`publish(i)` for i = 0, 1, ... at `rate_hz` for `seconds`, paced by sleeping (a spinning
    publisher would take a core from what it measures): whatever is due is sent, then a short sleep.
    Returns how many were sent."""
    start = time.perf_counter()
    sent = 0
    while (elapsed := time.perf_counter() - start) < seconds:
        due = min(int(elapsed * rate_hz) + 1, count) if count else int(elapsed * rate_hz) + 1
        while sent < due:
            publish(sent)
            sent += 1
        time.sleep(0.0002)
    return sent


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
    user, nice, system, idle, iowait, irq, softirq, steal = (
        int(f) for f in Path("/proc/stat").read_text().split()[1:9]
    )
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


class DdsCounter:
    """Raw rclpy subscribers on `topics` (a key -> (topic, ROS 2 type)) in a process of their own,
    counting what arrives on each while `counting` is set.

    The process takes the raw messages itself, every waiting one of each subscription in turn, then
    sleeps a millisecond when none waited. In the bench's own process the subscribers shared the GIL
    with its publisher, and an executor's `spin_once` costs tens of microseconds a message: at
    30,000 small messages a second, or 2,000 draws a second on three topics, that, not the bridge,
    bounded what was seen delivered. The process inherits this one's CPU affinity.
    """

    def __init__(self, topics: dict[str, tuple[str, str]]) -> None:
        spawn = multiprocessing.get_context("spawn")  # rclpy's state is not forked
        self.keys = list(topics)
        self.counting = spawn.Event()
        # Each written by the subscriber process's one thread only.
        self._counts = spawn.Array("q", len(topics), lock=False)
        self._totals = spawn.Array("q", len(topics), lock=False)  # every message, counting or not
        self._bridge = spawn.Event()  # the bridge's node (`viewer_bridge`) is in the ROS graph
        self._stop = spawn.Event()
        ready = spawn.Event()
        shared = (self.counting, self._counts, self._totals, self._bridge, self._stop, ready)
        self._process = spawn.Process(target=_count_raw, args=(list(topics.values()), *shared))
        self._process.start()
        if not ready.wait(60):
            self.close()
            raise RuntimeError("the rclpy subscriber process did not start within 60 s")

    @property
    def counts(self) -> dict[str, int]:
        return dict(zip(self.keys, self._counts, strict=True))

    @property
    def count(self) -> int:
        """Every topic's count, summed."""
        return sum(self._counts)

    @property
    def total(self) -> int:
        """Every message so far, counting or not."""
        return sum(self._totals)

    @property
    def seen(self) -> set[str]:
        """The keys whose topics have had a message."""
        return {key for key, total in zip(self.keys, self._totals, strict=True) if total}

    def sees_bridge(self) -> bool:
        return self._bridge.is_set()

    def close(self) -> None:
        self._stop.set()
        self._process.join(10)
        if self._process.is_alive():
            self._process.kill()


def _count_raw(topics: list[tuple[str, str]], counting: Any, counts: Any, totals: Any, bridge: Any, stop: Any,
               ready: Any) -> None:  # fmt: skip
    """The subscriber process of `DdsCounter`."""
    import rclpy
    from rclpy.node import Node

    from viewer_bridge.transports.ros2 import message_class, qos_profile

    rclpy.init()
    node = Node("bench_counter")
    kinds = [message_class(typename) for _, typename in topics]
    handles = [node.create_subscription(kind, topic, lambda _: None, qos_profile(1000), raw=True).handle
               for kind, (topic, _) in zip(kinds, topics, strict=True)]  # fmt: skip
    ready.set()
    look_at = 0.0
    while not stop.is_set():
        waited = False
        for index, (kind, handle) in enumerate(zip(kinds, handles, strict=True)):
            taken = 0
            with handle:
                while handle.take_message(kind, True) is not None:
                    taken += 1
            if taken:
                waited = True
                totals[index] += taken
                if counting.is_set():
                    counts[index] += taken
        if not bridge.is_set() and time.monotonic() > look_at:  # the graph, five times a second until seen
            look_at = time.monotonic() + 0.2
            if "viewer_bridge" in node.get_node_names():
                bridge.set()
        if not waited:
            time.sleep(0.001)
    node.destroy_node()  # type: ignore[no-untyped-call]
    rclpy.shutdown()


def flat_stats(document: dict[str, Any]) -> dict[str, Any]:
    """A `--stats-json` document as the benches read it, route names and `transports` at the top,
    whichever shape the bridge wrote: a baseline checkout may predate the versioned one (`schema`
    1: `routes` and `transports` apart, docs/configuration.md)."""
    if "schema" not in document:
        return document
    transports = {"transports": document["transports"]} if document.get("transports") else {}
    return {**document["routes"], **transports}
