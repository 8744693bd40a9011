"""Every child process a test starts runs in a process group of its own, and every group is killed
when the test ends, whatever happened in it.

A bridge, a Zenoh router, a Node.js client or a Drake simulation left running by a failed or hung
test would hold its ports and multicast groups and slow every later test on a shared machine;
and a child of a child (a shell's, npm's, colcon's) outlives a kill of its parent alone. So
`tests/conftest.py` swaps `subprocess.Popen` for `GroupedPopen` for the whole session: every
child (through `Popen`, `subprocess.run` or asyncio alike, in a test, a helper or a bench script a
test runs) starts a session of its own (`start_new_session=True`, unless its caller chose its
group itself), so its process group holds it and everything it starts, and `ChildGroups` kills
the groups a test started at that test's teardown: SIGTERM, then SIGKILL after a grace period.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

# How long a group has to end by itself after SIGTERM (a bridge stops its routes and transports)
# before SIGKILL, and how long the kernel gets to end a SIGKILLed group.
TERM_GRACE_S = 10.0
KILL_WAIT_S = 10.0


class ChildGroups:
    """The process groups of the children started in this process, by the test that started them."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._outside_tests: list[subprocess.Popen[Any]] = []  # started by wider fixtures, or between tests
        self._current: list[subprocess.Popen[Any]] = self._outside_tests
        self._original_popen: type[subprocess.Popen[Any]] | None = None

    def install(self) -> None:
        """From now on every `subprocess.Popen` of this process starts a group of its own, recorded here."""
        if self._original_popen is None:
            self._original_popen = subprocess.Popen
            subprocess.Popen = grouped_popen(self._original_popen, self)  # type: ignore[misc,assignment]

    def uninstall(self) -> None:
        if self._original_popen is not None:
            subprocess.Popen = self._original_popen  # type: ignore[misc,assignment]
            self._original_popen = None

    def add(self, child: subprocess.Popen[Any]) -> None:
        with self._lock:
            self._current.append(child)

    @contextmanager
    def test_scope(self, grace: float = TERM_GRACE_S) -> Iterator[None]:
        """The children started inside the block are ended when it exits, however it exits."""
        mine: list[subprocess.Popen[Any]] = []
        with self._lock:
            self._current = mine
        try:
            yield
        finally:
            with self._lock:
                self._current = self._outside_tests
            end_groups(mine, grace)

    def end_all(self, grace: float = TERM_GRACE_S) -> None:
        """Every group still recorded: at the session's end, or when a test passes its deadline."""
        with self._lock:
            children = list(self._outside_tests)
            if self._current is not self._outside_tests:
                children += self._current  # the running test's
            self._outside_tests.clear()
        end_groups(children, grace)


def grouped_popen(base: type[subprocess.Popen[Any]], groups: ChildGroups) -> type[subprocess.Popen[Any]]:
    """A `Popen` class that starts each child in a session of its own and records it in `groups`."""

    class GroupedPopen(base):  # type: ignore[valid-type,misc]
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            # A caller that chose the child's group itself keeps its choice (and its own cleanup).
            own_group = "process_group" not in kwargs and kwargs.get("start_new_session", True)
            if own_group:
                kwargs["start_new_session"] = True
            super().__init__(*args, **kwargs)
            if own_group:
                groups.add(self)

    return GroupedPopen


def end_groups(children: Iterable[subprocess.Popen[Any]], grace: float = TERM_GRACE_S) -> None:
    """SIGTERM to each child's process group that still has a live member, SIGKILL to those still
    live after `grace` seconds; the children themselves are reaped."""
    children = list(children)
    # With start_new_session the child leads its session and group: the group's id is its pid.
    groups = live_groups(child.pid for child in children)
    _signal_groups(groups, signal.SIGTERM)
    remaining = _wait_until_ended(groups, children, grace)
    _signal_groups(remaining, signal.SIGKILL)
    _wait_until_ended(remaining, children, KILL_WAIT_S)
    for child in children:
        child.poll()  # reaped, so no zombie and no "still running" warning at garbage collection


def live_groups(group_ids: Iterable[int]) -> set[int]:
    """Those of `group_ids` with at least one member that is not a zombie.

    Read from /proc rather than probed with a signal: a zombie still counts as a member for
    kill(), and a group whose leader exited may live on in its children.
    """
    wanted = set(group_ids)
    if not wanted:
        return set()
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:  # it ended while we looked
            continue
        # pid (comm) state ppid pgrp ...: comm may hold spaces and parentheses, so split after the last ')'.
        state, _ppid, group = stat.rpartition(")")[2].split()[:3]
        if state != "Z" and int(group) in wanted:
            found.add(int(group))
    return found


def _signal_groups(groups: Iterable[int], signum: signal.Signals) -> None:
    for group in groups:
        with contextlib.suppress(ProcessLookupError, PermissionError):  # ended meanwhile
            os.killpg(group, signum)


def _wait_until_ended(groups: set[int], children: list[subprocess.Popen[Any]], timeout: float) -> set[int]:
    """The groups still live after waiting up to `timeout` seconds for them to end."""
    deadline = time.monotonic() + timeout
    while groups:
        for child in children:
            child.poll()  # a leader that exited is reaped, so that it stops counting
        groups = live_groups(groups)
        if not groups or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    return groups
