"""Cores for worker processes: how many `--workers auto` runs, and whether workers compete for cores.

Every worker reads every LCM datagram (LCM has no per-channel socket: the kernel hands each
process that joined the multicast group its own copy), so a worker costs its receive work on top
of its routes' share. Where the machine has fewer free cores than the workers and their peers (the
simulation publishing, the viewers subscribing), a second worker takes a core the first one, the
publisher or a subscriber needed, and delivers less than one worker did. So:

- `usable_cores`, `busy_cores_now`: what `--workers auto` (`workers.auto_workers`) counts: a
  worker per core left free once `PEER_CORES` is kept for the peers (which the bridge cannot see
  before they start), and no more than the config's routes can use.
- `CoreWatch`: once per stats period, the time the workers' threads spent ready to run but waiting
  for a core (the scheduler's run-queue delay, /proc/PID/task/*/schedstat), against the time they
  ran; `competing` says when that delay is a large share of their work, with what the machine did.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

PEER_CORES = 1  # kept free for the publishers and subscribers on the same machine
WAIT_SHARE = 0.25  # run-queue delay per second run above which workers compete for cores
MIN_RUN_SHARE = 0.05  # of a core: below it the workers are idle, and their delays say nothing
_SAMPLE_S = 0.25  # how long `auto_workers` watches the machine before it counts free cores


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity: a container's or taskset's share)."""
    return len(os.sched_getaffinity(0))


def machine_busy_seconds() -> tuple[float, float]:
    """(busy, stolen) CPU seconds of the whole machine since boot, from /proc/stat's first line:
    busy is user, nice, system, irq and softirq time; stolen is what the hypervisor gave other guests."""
    fields = [int(value) for value in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    tick = os.sysconf("SC_CLK_TCK")
    user, nice, system, _idle, _iowait, irq, softirq, steal = (fields + [0] * 8)[:8]
    return (user + nice + system + irq + softirq) / tick, steal / tick


def run_and_wait_seconds(pid: int) -> tuple[float, float]:
    """(ran, waited) seconds of every thread of process `pid`: time on a core, and time ready to
    run but waiting for one (/proc/PID/task/TID/schedstat); (0, 0) for a process that has gone."""
    ran = waited = 0
    try:
        threads = list(Path(f"/proc/{pid}/task").iterdir())
    except OSError:
        return 0.0, 0.0
    for thread in threads:
        try:
            on_core, on_queue, _ = (thread / "schedstat").read_text().split()
        except (OSError, ValueError):  # the thread ended meanwhile
            continue
        ran, waited = ran + int(on_core), waited + int(on_queue)
    return ran / 1e9, waited / 1e9


def busy_cores_now(seconds: float = _SAMPLE_S) -> float:
    """How many cores the machine keeps busy, watched for `seconds`."""
    before, started = machine_busy_seconds()[0], time.monotonic()
    time.sleep(seconds)
    return (machine_busy_seconds()[0] - before) / (time.monotonic() - started)


@dataclass(frozen=True)
class CoreSample:
    """What the workers and the machine did over one period."""

    seconds: float  # the period's wall time
    workers: int  # processes running
    cores: int  # the cores they may use
    ran: float  # CPU seconds the workers' threads ran
    waited: float  # seconds they were ready to run but waited for a core
    machine_busy: float  # CPU seconds the whole machine used (every process, the kernel)
    stolen: float  # CPU seconds the hypervisor gave other guests


def competing(sample: CoreSample) -> str | None:
    """What to say when the workers compete for cores over `sample`, else None: their threads
    waited for a core at least `WAIT_SHARE` of the time they ran (and they ran at least
    `MIN_RUN_SHARE` of a core: idle workers' delays mean nothing)."""
    if sample.seconds <= 0 or sample.ran < MIN_RUN_SHARE * sample.seconds:
        return None
    share = sample.waited / sample.ran
    if share < WAIT_SHARE:
        return None
    stolen = f", {sample.stolen / sample.seconds:.2f} stolen by the hypervisor" if sample.stolen > 0 else ""
    return (
        f"the {sample.workers} workers compete for cores: they waited {share:.2f} s for a core per "
        f"second they ran (the machine used {sample.machine_busy / sample.seconds:.2f} of its "
        f"{sample.cores} cores{stolen}); each worker reads every LCM message, so on a machine this busy "
        "fewer workers deliver more: --workers auto counts the free cores"
    )


class CoreWatch:
    """The workers' run and wait times and the machine's, sampled each `sample(pids)`."""

    def __init__(self) -> None:
        self._last: tuple[float, dict[int, tuple[float, float]], tuple[float, float]] | None = None

    def sample(self, pids: list[int]) -> CoreSample | None:
        """Since the last call (None the first time, or when the workers changed meanwhile)."""
        now = time.monotonic()
        threads = {pid: run_and_wait_seconds(pid) for pid in pids}
        machine = machine_busy_seconds()
        last, self._last = self._last, (now, threads, machine)
        if last is None or set(last[1]) != set(threads):  # a worker restarted: its counts began anew
            return None
        before, earlier, machine_before = last
        return CoreSample(
            seconds=now - before,
            workers=len(pids),
            cores=usable_cores(),
            ran=sum(threads[pid][0] - earlier[pid][0] for pid in pids),
            waited=sum(threads[pid][1] - earlier[pid][1] for pid in pids),
            machine_busy=machine[0] - machine_before[0],
            stolen=machine[1] - machine_before[1],
        )
