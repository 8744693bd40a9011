"""A hung test is a named failure and never a stuck run: past its deadline the run ends with every
thread's stack and the test's name, and no child process of a test outlives it."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from tests.process_groups import end_groups, live_groups

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).relative_to(ROOT)
PROBE = "VIEWER_BRIDGE_DEADLINE_PROBE"  # the file the probes write their pids to: set only in the run below

# A shell whose own child is in its group: a kill of the shell alone would leave the sleep running.
SHELL_WITH_A_CHILD = ["bash", "-c", "sleep 600 & echo $! ; wait"]


def start_a_family(pids: Path) -> None:
    """A shell and its sleeping child, their pids appended to `pids` (read by the run outside)."""
    shell = subprocess.Popen(SHELL_WITH_A_CHILD, stdout=subprocess.PIPE, text=True)
    assert shell.stdout is not None
    grandchild = shell.stdout.readline().strip()
    with pids.open("a") as out:
        out.write(f"{shell.pid} {grandchild}\n")


if PROBE in os.environ:

    def test_probe_that_leaves_its_children_running() -> None:
        start_a_family(Path(os.environ[PROBE]))

    def test_probe_that_hangs() -> None:
        start_a_family(Path(os.environ[PROBE]))
        time.sleep(600)  # past the 2 s deadline the run outside sets


def alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie left to a parent that does not reap counts as ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return False
    return state != "Z"


def wait_until(condition: Callable[[], bool], timeout: float = 60.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.1)
    return False


def test_a_hung_test_fails_by_name_with_every_stack_and_leaves_no_child(tmp_path: Path) -> None:
    pids = tmp_path / "pids"
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-v", "--timeout", "2",
         f"{HERE}::test_probe_that_leaves_its_children_running", f"{HERE}::test_probe_that_hangs"],
        cwd=ROOT, env={**os.environ, PROBE: str(pids), "PYTHONPATH": str(ROOT)},
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    report = run.stdout + run.stderr
    assert run.returncode == 1, report
    assert f"{HERE}::test_probe_that_leaves_its_children_running PASSED" in report, report
    assert f"Timeout: {HERE}::test_probe_that_hangs ran past its 2 s" in report, report
    assert "Stack of MainThread" in report and "time.sleep(600)" in report, report  # where it hung
    families = [[int(pid) for pid in line.split()] for line in pids.read_text().splitlines()]
    assert len(families) == 2
    # The first test's children were ended at its teardown, the second's when its deadline passed:
    # shells and their own children alike.
    everyone = [pid for family in families for pid in family]
    assert wait_until(lambda: not any(alive(pid) for pid in everyone)), [
        pid for pid in everyone if alive(pid)
    ]


def test_a_group_that_ignores_sigterm_is_killed_after_the_grace() -> None:
    stubborn = subprocess.Popen(["bash", "-c", "trap '' TERM; sleep 600 & echo $!; wait"], stdout=subprocess.PIPE,
                                text=True)  # fmt: skip
    assert stubborn.stdout is not None
    sleeper = int(stubborn.stdout.readline())  # it ignores SIGTERM too: ignored signals are inherited
    started = time.monotonic()
    end_groups([stubborn], grace=1.0)
    assert time.monotonic() - started >= 1.0  # SIGTERM was tried first, for the whole grace
    assert stubborn.returncode == -9 and not alive(sleeper)
    assert live_groups([stubborn.pid]) == set()


def test_every_child_starts_a_group_of_its_own() -> None:
    child = subprocess.Popen(["sleep", "600"])
    try:
        assert os.getpgid(child.pid) == child.pid != os.getpgid(0)
    finally:
        end_groups([child], grace=10)
    assert child.returncode == -15  # it ended at SIGTERM, within the grace
