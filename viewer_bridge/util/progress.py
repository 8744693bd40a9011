"""Progress of long work, for the command line: a rich bar on a terminal; on a pipe (a script, a
log file), one plain line per step once the work has run `QUIET_S` seconds, so that quick work
prints nothing and long work is never silent. A step is a tenth of the total when the total is
known, else `EVERY_S` seconds.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from typing import TextIO

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    SpinnerColumn,
    TaskID,
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
) -> Iterator[Advance]:
    """Yields `advance(n)`: `n` more units of `total` (None: not known) done. `counted(done)` says
    how much in words (`5,100 of 17,000 events`); the lines start with `prefix` (`viewer-bridge convert`)."""
    out = sys.stderr if stream is None else stream
    if terminal if terminal is not None else out.isatty():
        with _bar(what, total) as advance:
            yield advance
        return
    started = time.monotonic()
    done = 0
    said_at = started  # when a line was last said (steps without a total)
    next_tenth = 1  # the next tenth of the total to say

    def step(size: int) -> None:
        nonlocal done, said_at, next_tenth
        done += size
        now = time.monotonic()
        if now - started < QUIET_S:
            return
        if total:
            tenth = min(10, done * 10 // total)
            if tenth < next_tenth:
                return
            next_tenth = tenth + 1
            share = f"{tenth * 10}%: "
        elif now - said_at < EVERY_S:
            return
        else:
            share = ""
        said_at = now
        print(f"{prefix}: {what}: {share}{counted(done)} ({now - started:.0f} s)", file=out, flush=True)

    yield step


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
    has been running, until the next, so a long build is visibly alive. `paused()` takes the
    spinner away while the user is asked something."""

    def __init__(self, terminal: bool | None = None, stream: TextIO | None = None) -> None:
        self._out = sys.stderr if stream is None else stream
        self._bar: Progress | None = None
        if terminal if terminal is not None else self._out.isatty():
            self._bar = Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                                 console=Console(file=self._out), transient=True)  # fmt: skip
        self._task: TaskID | None = None

    def say(self, line: str) -> None:
        if self._bar is None:
            print(line, file=self._out, flush=True)
            return
        self._bar.console.print(line, highlight=False, markup=False)
        if self._task is not None:
            self._bar.remove_task(self._task)
        self._task = self._bar.add_task(line, total=None)
        self._bar.start()

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
