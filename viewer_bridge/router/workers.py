"""Worker processes: one config's routes over several processes (`viewer-bridge run --workers N`).

One Python process translates on one core at a time (the GIL). With `workers: N` the routes are
placed on N child processes by their source, and each child is an ordinary `Router` over its
share of the config: it opens its own transports (an LCM multicast bus hands every process its
own copy of each message), its own load cache and its own loop guard. The parent opens no
transport: it starts the workers, merges the stats each one sends it once per period into the
one status view and `--stats-json`, restarts a worker that dies (counted and logged; the others
run on), and on Ctrl-C or SIGTERM stops them all and waits for them.

Placement (`place`): a route pinned with `worker: K` runs on worker K. The others are grouped by
source, transport and pattern, and groups that may read a same channel (one's pattern matches a
name the other's reads) are merged: routes that read the same messages share one receive, one
decode and one stream state, and stay together. Each group goes to the worker with the fewest
routes so far, or to worker 0 when it reads what a route kept there reads. Only routes whose
transports may be opened by several processes at once (`Transport.several_processes`: a bus,
not a server's port or a file) leave worker 0.

Every worker still reads every LCM datagram (LCM has no per-channel socket), so on a machine
with fewer free cores than the workers and their peers a worker costs more than it brings: the
parent watches how long its workers wait for a core and says so (`viewer_bridge.router.cores`),
and `--workers auto` counts the free cores.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
import multiprocessing
import os
import re
import signal
import string
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import NamedTuple

from viewer_bridge.config.bridge import BridgeConfig, Route
from viewer_bridge.errors import BridgeError, UsageError
from viewer_bridge.router import stats
from viewer_bridge.router.cores import PEER_CORES, CoreWatch, busy_cores_now, competing, usable_cores
from viewer_bridge.router.router import Router
from viewer_bridge.router.status import LogLines, RouteSnapshot, Snapshot, StatusView, snapshot_of
from viewer_bridge.transports.registry import TRANSPORTS
from viewer_bridge.util.words import counted

log = logging.getLogger("viewer_bridge")

# spawn: a fresh interpreter per worker, never a fork of a parent that may hold threads and locks.
_CONTEXT = multiprocessing.get_context("spawn")
_POLL = 0.1  # seconds between the parent's looks at its workers
_STOP_WAIT = 15.0  # seconds a stopping worker has to close its transports before it is killed
_RESTART_DELAY_MAX = 10.0  # the longest wait before restarting a worker that keeps dying at start
_COMPETING_REPEAT_S = 60.0  # while workers compete for cores, said again at most this often


class Started(NamedTuple):
    """A worker's first message: its router has started (its routes are subscribed)."""

    pid: int


class Stats(NamedTuple):
    """A worker's stats, once per stats period and once as it stops (`Router.snapshot`'s)."""

    stats: Snapshot


# What a worker sends its parent over its pipe: small records, pickled as a class name and a tuple.
WorkerMessage = Started | Stats


def place(config: BridgeConfig, workers: int) -> list[list[Route]]:
    """The config's routes on `workers` processes (see the module's docstring); a list per worker."""
    placed: list[list[Route]] = [[] for _ in range(workers)]
    groups: dict[tuple[str, str], list[Route]] = {}
    for route in config.routes:
        if route.worker is not None:
            if route.worker >= workers:
                raise UsageError(
                    f"route {route.name}: worker: {route.worker}, but the bridge runs {counted(workers, 'worker')} "
                    f"(0 to {workers - 1}; --workers or the config's workers: sets how many)"
                )
            placed[route.worker].append(route)
        elif _spreadable(route):
            groups.setdefault((route.source.transport, route.source.name), []).append(route)
        else:
            placed[0].append(route)
    for group in _sharing(list(groups.values())):
        # A group that reads what a route kept on worker 0 reads joins it there: one receive and
        # one decode of those messages, not a second worker's for the same ones.
        if workers > 1 and any(_overlap(group[0], route) for route in placed[0] if route.worker is None):
            placed[0].extend(group)
            continue
        fewest = min(range(workers), key=lambda index: len(placed[index]))
        placed[fewest].extend(group)
    return placed


def _sharing(groups: list[list[Route]]) -> list[list[Route]]:
    """`groups` (routes of one source pattern each), those that may read a same channel merged,
    in the order of their first route."""
    merged: list[list[Route]] = []
    for group in groups:
        joined = [other for other in merged if _overlap(group[0], other[0])]
        whole = [route for other in joined for route in other] + group
        merged = [other for other in merged if not any(other is j for j in joined)] + [whole]
    order = {id(route): index for index, group in enumerate(groups) for route in group}
    return sorted((sorted(group, key=lambda r: order[id(r)]) for group in merged),
                  key=lambda group: order[id(group[0])])  # fmt: skip


def _overlap(one: Route, other: Route) -> bool:
    """Whether two routes may read a same channel: one's pattern matches a name the other's reads
    (`_examples`: a sample of them). A guess that errs one way: an overlap it misses only costs a
    second receive and decode, as placing by pattern alone did."""
    if one.source.transport != other.source.transport:
        return False
    first, second = re.compile(one.source.name), re.compile(other.source.name)
    return any(second.fullmatch(name) for name in _examples(one.source.name)) or any(
        first.fullmatch(name) for name in _examples(other.source.name)
    )


_MAX_EXAMPLES = 64
_MAX_REPEAT = 64  # a `{m}` past this: no sample (a name m characters long is no likely channel)
# A character an item like `.`, `[^<>]` or `\d` matches: the first of these it takes.
_CANDIDATES = "x0_Z/-." + string.ascii_letters + string.digits + string.punctuation + " "
_REPEAT = re.compile(r"(?:(?P<none>[?*])|(?P<once>\+)|\{(?P<low>\d*)(?:,\d*)?\})[?+]?")
_LOOKAROUND = ("(?=", "(?!", "(?<=", "(?<!")
_FLAGS = re.compile(r"\(\?[aiLmsux]*(?:-[imsx]+)?[:)]")

# `_examples` reads a pattern with a reader of its own, small and of the forms a source pattern
# uses (CPython's own parser, `re._parser`, is private and changes between versions): literal
# characters and escaped punctuation, groups `(...)`, `(?:...)`, `(?P<name>...)`, alternatives,
# `? * + {m,n}`, `.`, sets `[...]`, `\d \w \s` and flags `(?i)`; anchors and lookarounds stand for
# no character. Any other form (a backreference, a comment) gives no sample: the other route's names are
# still tried against the pattern, and an overlap missed costs a second receive (see `_overlap`).
_Names = list[str] | None  # the names a part of a pattern stands for (a sample); None: a form not read


@functools.cache
def _examples(pattern: str) -> frozenset[str]:
    """Names `pattern` matches, a sample: each branch's, an optional part with and without, the
    fewest repeats otherwise, a set's first member; none for a form not read. Lookarounds and
    anchors are left out while sampling, so a name is kept only when the pattern matches it."""
    names, end = _alternatives(pattern, 0)
    if names is None or end != len(pattern):
        return frozenset()
    whole = re.compile(pattern)
    return frozenset(name for name in names if whole.fullmatch(name))


def _alternatives(pattern: str, at: int) -> tuple[_Names, int]:
    """The names of the `|`-separated branches from `at` to a `)` or the end, and where they stop."""
    names: list[str] = []
    while True:
        branch, at = _sequence(pattern, at)
        if branch is None:
            return None, at
        names = (names + branch)[:_MAX_EXAMPLES]
        if not pattern.startswith("|", at):
            return names, at
        at += 1


def _sequence(pattern: str, at: int) -> tuple[_Names, int]:
    """The names of the items from `at` to a `|`, a `)` or the end, each repeated as it says."""
    names = [""]
    while at < len(pattern) and pattern[at] not in "|)":
        choices, at = _item(pattern, at)
        if choices is None:
            return None, at
        repeat = _REPEAT.match(pattern, at)
        if repeat is not None:
            at = repeat.end()
            low = 1 if repeat["once"] else 0 if repeat["none"] or not repeat["low"] else int(repeat["low"])
            if low > _MAX_REPEAT:
                return None, at
            choices = ([""] if low == 0 else []) + [choice * max(low, 1) for choice in choices]
        names = [name + choice for name in names for choice in choices][:_MAX_EXAMPLES]
    return names, at


def _item(pattern: str, at: int) -> tuple[_Names, int]:
    """The names one item at `at` stands for (a group, a set, an escape, a character), and its end."""
    char = pattern[at]
    if char == "(":
        return _group(pattern, at)
    if char == "[":
        end = _set_end(pattern, at)
        return _one_character(pattern[at:end]), end
    if char == "\\":
        return _escape(pattern[at : at + 2]), at + 2
    if char in "^$":
        return [""], at + 1  # an anchor: no character of its own
    if char == ".":
        return _one_character(char), at + 1
    if char in "*+?":
        return None, at  # a repeat of nothing: no pattern `re` compiles
    return [char], at + 1


def _escape(pair: str) -> _Names:
    r"""What an escape stands for: an anchor (`\A \Z \b \B`) no character, a class (`\d \w \s`,
    their opposites) one, an escaped punctuation character itself; None for any other form (a
    backreference, a character by its code)."""
    if pair in ("\\A", "\\Z", "\\b", "\\B"):
        return [""]
    if pair in ("\\d", "\\D", "\\w", "\\W", "\\s", "\\S"):
        return _one_character(pair)
    return [pair[1]] if len(pair) == 2 and not pair[1].isalnum() else None


def _group(pattern: str, at: int) -> tuple[_Names, int]:
    """The names of the group at `at` (a lookaround: none of its own, "") and where it ends."""
    if pattern.startswith(_LOOKAROUND, at):
        inner = at + (4 if pattern.startswith("(?<", at) else 3)
    elif pattern.startswith("(?:", at):
        inner = at + 3
    elif pattern.startswith("(?P<", at) and ">" in pattern[at:]:
        inner = pattern.index(">", at) + 1
    elif flags := _FLAGS.match(pattern, at):  # `(?i)` no character of its own; `(?i:...)` a group
        if flags[0].endswith(")"):
            return [""], flags.end()
        inner = flags.end()
    elif pattern.startswith("(?", at):
        return None, at  # a backreference by name, a comment, a condition
    else:
        inner = at + 1
    names, end = _alternatives(pattern, inner)
    if names is None or not pattern.startswith(")", end):
        return None, end
    return ([""] if pattern.startswith(_LOOKAROUND, at) else names), end + 1


def _set_end(pattern: str, at: int) -> int:
    """Where the set `[...]` at `at` ends (past its `]`; a `]` first in it is a member)."""
    end = at + 1
    end += pattern.startswith("^", end)
    end += pattern.startswith("]", end)
    while end < len(pattern) and pattern[end] != "]":
        end += 2 if pattern[end] == "\\" else 1
    return end + 1


def _one_character(item: str) -> _Names:
    """The first candidate character a one-character `item` (`.`, a set, a digit's escape) matches."""
    try:
        matches = re.compile(item).fullmatch
    except re.error:
        return None
    return next(([char] for char in _CANDIDATES if matches(char)), None)


def _spreadable(route: Route) -> bool:
    """Whether a route may run outside worker 0: every process may open both of its transports."""
    ends = (route.source.transport, route.destination.transport)
    return all(TRANSPORTS.get(name).several_processes for name in ends)


def useful_workers(config: BridgeConfig) -> int:
    """The most workers `config`'s routes can use: a worker per group of routes `place` makes, and
    at least one past every route's `worker: K`."""
    pinned = max((route.worker + 1 for route in config.routes if route.worker is not None), default=1)
    groups = sum(1 for routes in place(config, max(pinned, len(config.routes), 1)) if routes)
    return max(groups, pinned, 1)


class WorkerCount(NamedTuple):
    """What `--workers auto` chose, and from what."""

    workers: int
    cores: int  # usable by the bridge
    busy: float  # cores the machine kept busy before the bridge started
    useful: int  # the most workers the routes can use

    def why(self) -> str:
        return (
            f"--workers auto: {self.workers} ({self.cores} usable cores, {self.busy:.1f} busy, "
            f"{PEER_CORES} kept for the peers; the routes can use {self.useful})"
        )


def auto_workers(config: BridgeConfig, cores: int | None = None, busy: float | None = None) -> WorkerCount:
    """`--workers auto`: the cores free of other work (`cores`: default this process's usable cores;
    `busy`: default how many cores the machine keeps busy now), less `PEER_CORES`, at most
    `useful_workers(config)`, at least 1 (and enough for every route's `worker: K`)."""
    cores = usable_cores() if cores is None else cores
    busy = busy_cores_now() if busy is None else busy
    spare = math.floor(max(0.0, cores - busy) + 0.25) - PEER_CORES  # 0.75 of a core free counts as one
    pinned = max((route.worker + 1 for route in config.routes if route.worker is not None), default=1)
    useful = useful_workers(config)
    return WorkerCount(max(1, pinned, min(spare, useful)), cores, busy, useful)


@dataclass
class _Worker:
    """One worker's slot: its routes, its current process, and what it last said."""

    index: int
    config: BridgeConfig  # the config with only this worker's routes
    process: BaseProcess | None = None
    connection: Connection | None = None  # the parent's end: `WorkerMessage`s arrive here
    started: bool = False  # the current process has started its router
    ever_started: bool = False
    finished: bool = False  # it ended on its own, as a router ends when its replayed log has
    failures: int = 0  # deaths in a row before it started: the wait before the next try doubles
    restart_at: float | None = None
    snapshot: Snapshot = field(default_factory=lambda: snapshot_of({}, {}))  # its router's last

    def routes(self) -> str:
        return ", ".join(route.name for route in self.config.routes)

    def alive(self) -> bool:
        return self.process is not None and self.process.exitcode is None


class Workers:
    """A config's routes on worker processes: `start`, `run`, `stop` as a `Router`'s."""

    def __init__(
        self,
        config: BridgeConfig,
        workers: int,
        stats_json: str | Path | None = None,
        stats_period: float = 5.0,
        view: StatusView | None = None,
    ) -> None:
        self.config = config
        self.stats_json = Path(stats_json) if stats_json else None
        self.stats_period = stats_period
        self.view = view or LogLines()
        self.restarts = 0
        self.competing = 0  # stats periods in which the workers competed for cores (`cores.competing`)
        self._cores = CoreWatch()
        self._competing_said_at: float | None = None
        self._stop = threading.Event()
        self._started = False
        self._workers = [
            _Worker(index, config.model_copy(update={"routes": routes, "workers": 1}))
            for index, routes in enumerate(place(config, workers))
            if routes  # more workers than groups of routes: the rest have nothing to do
        ]

    def start(self) -> None:
        """Start every worker and wait until each has started its router (subscribed), or raise
        `BridgeError` if one ends before it did (it said why on stderr). Once: `run` calls it too."""
        if self._started:
            return
        self._started = True
        for worker in self._workers:
            self._spawn(worker)
        try:
            while not self._stop.is_set() and not all(worker.started for worker in self._workers):
                self._poll(restart=False)
        except BaseException:
            self.close()
            raise
        if not self._stop.is_set():
            log.info("viewer-bridge: %s running", counted(len(self._workers), "worker"))

    def _spawn(self, worker: _Worker) -> None:
        receiver, sender = _CONTEXT.Pipe(duplex=False)
        level = log.getEffectiveLevel()
        process = _CONTEXT.Process(
            target=_serve, args=(worker.index, worker.config, self.stats_period, sender, level),
            name=f"viewer-bridge worker {worker.index}", daemon=False,
        )  # fmt: skip
        # The worker starts with SIGINT blocked (a signal mask survives fork and exec): a Ctrl-C
        # at the terminal reaches the whole process group, and the parent alone decides what it
        # means; it stops its workers with SIGTERM. Unblocked here at once: none is lost.
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        sender.close()  # the worker's end: the parent keeps only its own, so a dead worker reads as EOF
        worker.process, worker.connection, worker.started, worker.restart_at = process, receiver, False, None
        log.info("viewer-bridge: worker %d (pid %s): %s", worker.index, process.pid, worker.routes())

    def _poll(self, restart: bool = True) -> None:
        """Read what the workers sent, and look after the dead ones (restarted if `restart`)."""
        connections = [worker.connection for worker in self._workers if worker.connection is not None]
        multiprocessing.connection.wait(connections, timeout=_POLL)
        for worker in self._workers:
            self._read(worker)
            if worker.process is not None and worker.process.exitcode is not None:
                self._ended(worker, restart)
            elif worker.restart_at is not None and time.monotonic() >= worker.restart_at:
                self._spawn(worker)

    def _read(self, worker: _Worker) -> None:
        """Every message waiting from a worker: `Started` once, then `Stats`."""
        while worker.connection is not None and worker.connection.poll():
            try:
                message = worker.connection.recv()
            except (EOFError, OSError):  # the worker is gone; its exit is seen next
                worker.connection.close()
                worker.connection = None
                return
            if isinstance(message, Started):
                worker.started = worker.ever_started = True
                worker.failures = 0
            elif isinstance(message, Stats):
                worker.snapshot = message.stats

    def _ended(self, worker: _Worker, restart: bool) -> None:
        """A worker's process has ended: finished, or died (restarted unless the start failed)."""
        assert worker.process is not None
        code = worker.process.exitcode
        self._read(worker)
        worker.process.close()
        worker.process = None
        if worker.connection is not None:
            worker.connection.close()
            worker.connection = None
        if code == 0:
            worker.finished = worker.started = True  # its source ended (a replayed log)
            return
        how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
        if not (restart and worker.ever_started):
            raise BridgeError(f"worker {worker.index} ({worker.routes()}) stopped before it started ({how})")
        self.restarts += 1
        worker.failures += 0 if worker.started else 1
        delay = min(_RESTART_DELAY_MAX, 0.5 * 2 ** (worker.failures - 1)) if worker.failures else 0.0
        log.warning("viewer-bridge: worker %d died (%s): restarting it%s (%s so far); the other workers run on",
                    worker.index, how, f" in {delay:g} s" if delay else "",
                    counted(self.restarts, "restart"))  # fmt: skip
        worker.started = False
        worker.restart_at = time.monotonic() + delay

    def _watch_cores(self) -> None:
        """Whether the workers competed for cores since the last look: counted, and said (once a
        minute at most while it lasts)."""
        pids = [worker.process.pid for worker in self._workers if worker.alive() and worker.process]
        sample = self._cores.sample([pid for pid in pids if pid is not None])
        said = competing(sample) if sample is not None else None
        if said is None:
            return
        self.competing += 1
        now = time.monotonic()
        if self._competing_said_at is None or now - self._competing_said_at >= _COMPETING_REPEAT_S:
            self._competing_said_at = now
            log.warning("viewer-bridge: %s", said)

    def stop(self) -> None:
        """Stop the workers and return from `run` (a signal handler calls it)."""
        self._stop.set()

    def run(self, duration: float | None = None) -> None:
        """Serve until `stop()`, `duration` ends, or every worker has finished on its own."""
        self.start()
        deadline = None if duration is None else time.monotonic() + duration
        next_report = time.monotonic() + self.stats_period
        try:
            while not self._stop.is_set() and (deadline is None or time.monotonic() < deadline):
                if all(worker.finished for worker in self._workers):
                    log.info("viewer-bridge: every worker has finished: stopping")
                    break
                self._poll()
                if time.monotonic() >= next_report:
                    next_report += self.stats_period
                    self._watch_cores()
                    self.report()
        finally:
            self.close()

    def close(self) -> None:
        """Stop every worker (SIGTERM: each closes its router and sends its last stats), wait for
        them (killed after `_STOP_WAIT` s), and write the last merged stats."""
        for worker in self._workers:
            if worker.alive():
                assert worker.process is not None and worker.process.pid is not None
                os.kill(worker.process.pid, signal.SIGTERM)
        deadline = time.monotonic() + _STOP_WAIT
        while any(worker.alive() for worker in self._workers):
            if time.monotonic() >= deadline:
                for worker in self._workers:
                    if worker.alive():
                        assert worker.process is not None
                        log.warning("viewer-bridge: worker %d did not stop: killing it", worker.index)
                        worker.process.kill()
                        worker.process.join()
            for worker in self._workers:
                self._read(worker)  # a worker blocked writing its last stats must be read to end
                if worker.process is not None:
                    worker.process.join(_POLL / len(self._workers))
        for worker in self._workers:
            self._read(worker)
        self.report()
        self.view.close()

    def processes(self) -> list[int]:
        """The worker slots (one process each while running), by index."""
        return [worker.index for worker in self._workers]

    def snapshot(self) -> Snapshot:
        """Every worker's last stats as one router's: routes in the config's order, the transports'
        error counts summed, and the restarts as the errors of `workers`."""
        routes: dict[str, RouteSnapshot] = {}
        for worker in self._workers:
            routes.update(worker.snapshot["routes"])
        errors: dict[str, Counter[str]] = {}
        for worker in self._workers:
            for name, entry in worker.snapshot["transports"].items():
                errors.setdefault(name, Counter()).update(entry["errors"])
        if self.restarts:
            errors["workers"] = Counter(restarted=self.restarts)
        in_order = {route.name: routes[route.name] for route in self.config.routes if route.name in routes}
        return snapshot_of(in_order, {name: dict(counts) for name, counts in errors.items()})

    def report(self) -> None:
        """The routes' stats to the status view, and to the JSON file when asked for."""
        stats.report_safely(self.snapshot, self.view, self.stats_json)


class _Sender:
    """A worker's status view: each snapshot goes to the parent, which shows them merged."""

    def __init__(self, connection: Connection) -> None:
        self._connection = connection

    def show(self, snapshot: Snapshot) -> None:
        with contextlib.suppress(OSError):  # the parent is gone: the watch on it stops this worker
            self._connection.send(Stats(snapshot))

    def close(self) -> None:
        pass


def _serve(index: int, config: BridgeConfig, stats_period: float, connection: Connection, level: int) -> None:
    """A worker process: its routes' router, until SIGTERM or its parent ends."""
    # Ctrl-C reaches the whole process group: the parent alone answers it (it stops its workers
    # with SIGTERM), so a worker ignores it for good, whatever a library unblocks or installs.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.basicConfig(level=level, format=f"%(asctime)s worker {index}: %(message)s", datefmt="%H:%M:%S")
    try:
        router = Router(config, stats_period=stats_period, view=_Sender(connection))
    except BridgeError as error:
        log.error("viewer-bridge run: %s", error)
        raise SystemExit(2) from None
    stopped = threading.Event()  # a worker exits 0 only when it ended on its own (its log replayed)

    def stop(*_: object) -> None:
        stopped.set()
        router.stop()

    signal.signal(signal.SIGTERM, stop)
    parent = multiprocessing.parent_process()
    if parent is not None:  # a parent killed outright leaves no worker behind

        def orphaned() -> None:
            parent.join()
            stop()

        threading.Thread(target=orphaned, daemon=True).start()
    router.start()
    connection.send(Started(os.getpid()))
    router.run()
    if stopped.is_set():
        raise SystemExit(128 + signal.SIGTERM)
