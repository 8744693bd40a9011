"""Progress of long work, for the command line: a rich bar on a terminal; on a pipe (a script, a
log file), one plain line per step once the work has run `QUIET_S` seconds, so that quick work
prints nothing and long work is never silent. A step is a tenth of the total when the total is
known, else `EVERY_S` seconds.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import TextIO

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    SpinnerColumn,
    TaskID,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

QUIET_S = 2.0  # work shorter than this shows no progress on a pipe
EVERY_S = 5.0  # a pipe's step when the total is not known

Advance = Callable[[int], None]


@contextlib.contextmanager
def progress(
    prefix: str,
    what: str,
    total: int | None,
    counted: Callable[[int], str],
    terminal: bool | None = None,
    stream: TextIO | None = None,
    started: float | None = None,
) -> Iterator[Advance]:
    """Yields `advance(n)`: `n` more units of `total` (None: not known) done. `counted(done)` says
    how much in words (`5,100 of 17,000 events`); the lines start with `prefix` (`viewer-bridge convert`).
    `started` (a `time.monotonic()`, default now) is when the work began, when its size was
    known only after some of it (the types read before they are written)."""
    out = sys.stderr if stream is None else stream
    if terminal if terminal is not None else out.isatty():
        with _bar(what, total) as advance:
            yield advance
        return
    pace = _Pace(total, started)
    done = 0

    def step(size: int) -> None:
        nonlocal done
        done += size
        share = pace.due(done)
        if share is not None:
            print(f"{prefix}: {what}: {share}{counted(done)} ({pace.seconds():.0f} s)", file=out, flush=True)

    yield step


class _Pace:
    """When a pipe hears of work under way: not in its first QUIET_S seconds, then at each new
    tenth of `total` (or every EVERY_S seconds without one)."""

    def __init__(self, total: int | None, started: float | None = None) -> None:
        self.total = total
        self._started = self._said_at = time.monotonic() if started is None else started
        self._next_tenth = 1

    def seconds(self) -> float:
        return time.monotonic() - self._started

    def due(self, done: int) -> str | None:
        """None when nothing is to be said of `done` now, else the share to say (`40%: `, or
        nothing without a total)."""
        now = time.monotonic()
        if now - self._started < QUIET_S:
            return None
        if self.total:
            tenth = min(10, done * 10 // self.total)
            if tenth < self._next_tenth:
                return None
            self._next_tenth = tenth + 1
            share = f"{tenth * 10}%: "
        elif now - self._said_at < EVERY_S:
            return None
        else:
            share = ""
        self._said_at = now
        return share


@contextlib.contextmanager
def _bar(what: str, total: int | None) -> Iterator[Advance]:
    columns = (
        TextColumn(what),
        BarColumn(),
        TextColumn("{task.percentage:>3.0f}%" if total else "{task.completed:,}"),
        TimeRemainingColumn() if total else TimeElapsedColumn(),
    )
    with Progress(*columns, transient=True, console=Console(stderr=True)) as bar:
        task = bar.add_task(what, total=total)

        def advance(size: int) -> None:
            bar.advance(task, size)

        yield advance


class Steps:
    """Work told in steps (`building tf2_msgs ...`, `built tf2_msgs in 9.7 s`): `say(line)` prints
    each as it comes; on a terminal the last one also stays below as a spinner with the seconds it
    has been running, until the next, so a long build is visibly alive. `part(what, done, total)`
    tells how far a part of known size has come (a package's build steps): a bar below on a
    terminal, a line per tenth on a pipe once the part has run QUIET_S seconds. `paused()` takes the
    spinner away while the user is asked something. Steps may be told from several threads."""

    def __init__(self, terminal: bool | None = None, stream: TextIO | None = None) -> None:
        self._out = sys.stderr if stream is None else stream
        self._bar: Progress | None = None
        if terminal if terminal is not None else self._out.isatty():
            self._bar = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(bar_width=20),
                                 TaskProgressColumn(), TimeElapsedColumn(),
                                 console=Console(file=self._out), transient=True)  # fmt: skip
        self._task: TaskID | None = None
        self._parts: dict[str, tuple[_Pace, TaskID | None]] = {}
        self._lock = threading.Lock()

    def say(self, line: str) -> None:
        with self._lock:
            if self._bar is None:
                print(line, file=self._out, flush=True)
                return
            self._bar.console.print(line, highlight=False, markup=False)
            if self._task is not None:
                self._bar.remove_task(self._task)
            self._task = self._bar.add_task(line, total=None)
            self._bar.start()

    def part(self, what: str, done: int, total: int, counted: Callable[[int], str]) -> None:
        """`done` of `total` units of `what` (`building drake_lcm_msgs`) are done; `counted(done)`
        says so in words (`70 of 140 build steps`). The part ends when `done` reaches `total`."""
        with self._lock:
            if what not in self._parts:
                task = None if self._bar is None else self._bar.add_task(what, total=total)
                self._parts[what] = (_Pace(total), task)
            pace, task = self._parts[what]
            if self._bar is not None and task is not None:
                self._bar.update(task, completed=done, total=total)
                if done >= total:
                    self._bar.remove_task(task)
            else:
                pace.total = total
                share = pace.due(done)
                if share is not None:
                    print(
                        f"{what}: {share}{counted(done)} ({pace.seconds():.0f} s)", file=self._out, flush=True
                    )
            if done >= total:
                del self._parts[what]

    @contextlib.contextmanager
    def paused(self) -> Iterator[None]:
        if self._bar is not None:
            self._bar.stop()
        yield

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()


@contextlib.contextmanager
def steps(terminal: bool | None = None, stream: TextIO | None = None) -> Iterator[Steps]:
    """`Steps` on `stream` (stderr), its spinner gone at the end."""
    told = Steps(terminal, stream)
    try:
        yield told
    finally:
        told.close()
