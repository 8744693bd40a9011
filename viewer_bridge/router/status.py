"""How `viewer-bridge run` shows its routes: a live table on a terminal, log lines elsewhere.

The router hands a view a snapshot of every route's counters once per stats period
(`Router.snapshot`); the view alone decides how it looks. On a terminal, `LiveTable` keeps one
table on screen, a row per route that carries traffic or has a subscriber, with rates per second
since the last snapshot (a row that sends nothing for want of a subscriber says so in its `idle`
cell, in the words of the logged line); lazy routes that receive traffic nobody subscribes to are
one line (`waiting for a subscriber`, with their in-rates), the routes with no traffic another,
and a legend explains the counters that appear; it fits the terminal's width without cutting a
number.
Logs, CI and pipes get `LogLines`: a plain line per route with traffic (or losses), the same
text every period, easy to grep, the same two lines, and the legend of each counter the first
time it appears.
"""

from __future__ import annotations

import logging
import textwrap
import time
from collections.abc import Callable, Iterable
from typing import Any, Final, Literal, Protocol, TypedDict

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from viewer_bridge.util.words import counted

log = logging.getLogger("viewer_bridge")

# The shape of a stats snapshot: what the router hands its view each period, what a worker sends
# its parent, and what `--stats-json` writes (docs/configuration.md, "Flow, errors and stats").
# Plain dicts when the program runs (pickled through a worker's pipe, dumped as JSON as they are);
# the types say which keys each holds. A change of a key or its meaning is a new STATS_SCHEMA.
STATS_SCHEMA: Final = 1


class Percentiles(TypedDict):
    """The recent samples' percentiles in ms, rounded to 0.1 us; None before the first sample."""

    p50: float | None
    p99: float | None
    max: float | None


class RouteSnapshot(TypedDict):
    """A route's counters (`RouteStats.snapshot`), since the bridge started."""

    state: str  # "active", or why a lazy route translates nothing ("idle: no subscriber")
    messages_in: int
    messages_out: int
    bytes_in: int
    bytes_out: int
    idle_skipped: int
    qos_incompatible: int
    streams_reclaimed: int
    errors: dict[str, int]  # by kind (the exception's class, or a named cause)
    warnings: dict[str, int]  # by kind
    held: dict[str, dict[str, int]]  # channel -> kind -> messages held back on purpose
    superseded: int
    mailbox_full: int
    dropped: int  # superseded + mailbox_full
    max_hz_skipped: int
    queued: int  # waiting in the route's mailbox now
    translate_ms: Percentiles
    latency_ms: Percentiles
    unsent: int  # given to the destination's transport, which could not send it


class TransportSnapshot(TypedDict):
    """A transport's own error counts, by kind (`dropped_by_kernel`, `unsent_no_router`, `restarted`)."""

    errors: dict[str, int]


class Snapshot(TypedDict):
    """Every route's counters, by name in the config's order, and the transports' own errors."""

    schema: int  # STATS_SCHEMA
    routes: dict[str, RouteSnapshot]
    transports: dict[str, TransportSnapshot]  # only the transports that counted an error


def snapshot_of(routes: dict[str, RouteSnapshot], transports: dict[str, dict[str, int]]) -> Snapshot:
    """A snapshot of `routes`' counters and the transports' error counts (those with none left out)."""
    return {
        "schema": STATS_SCHEMA,
        "routes": routes,
        "transports": {name: {"errors": counts} for name, counts in transports.items() if counts},
    }


class StatusView(Protocol):
    def show(self, snapshot: Snapshot) -> None:
        """The routes' counters now (called once per stats period, and once at the end)."""

    def close(self) -> None:
        """The bridge is stopping: leave the last state on screen."""


def errors_of(stats: RouteSnapshot) -> int:
    return sum(stats["errors"].values())


def warnings_of(stats: RouteSnapshot) -> int:
    """What a route left out but carried on with (a geometry a target cannot draw, say)."""
    return sum(stats["warnings"].values())


def held_of(stats: RouteSnapshot) -> str:
    """Messages held back on purpose, by kind with their channels: `unknown_type 12 (FOO, BAR)`."""
    kinds: dict[str, tuple[int, list[str]]] = {}
    for channel, counts in stats.get("held", {}).items():
        for kind, count in counts.items():
            total, channels = kinds.get(kind, (0, []))
            kinds[kind] = (total + count, [*channels, channel])
    return ", ".join(f"{kind} {total} ({', '.join(channels)})" for kind, (total, channels) in kinds.items())


def unsent_of(stats: RouteSnapshot) -> int:
    """What a route published that its transport could not send (a Zenoh session with no router)."""
    return int(stats.get("unsent", 0))


def transports_line(transports: dict[str, TransportSnapshot]) -> str:
    """The transports' own error counts in words: `zenoh: 366 unsent no router; lcm: 3 dropped by kernel`."""
    return "; ".join(
        f"{name}: "
        + ", ".join(f"{count} {kind.replace('_', ' ')}" for kind, count in entry["errors"].items())
        for name, entry in transports.items()
    )


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


# What a route could not carry, by cause, as the stats name them (0 is not shown).
Loss = Literal["superseded", "mailbox_full", "max_hz_skipped", "unsent", "qos_incompatible"]
LOSSES: tuple[Loss, ...] = ("superseded", "mailbox_full", "max_hz_skipped", "unsent", "qos_incompatible")

# What each counter that may appear means, in a few words: the legend names those that appear
# (docs/configuration.md, "Flow, errors and stats", says more of each). `held` kinds too.
LEGEND = {
    "superseded": "a newer message on its channel came first (policy latest: the newest is sent)",
    "mailbox_full": "the oldest waiting message pushed out (policy all: qos.depth was full)",
    "max_hz_skipped": "superseded while the route waited out its rate.max_hz (by design)",
    "unsent": "given to a transport that could not send it (a Zenoh session with no router, no Rerun viewer)",
    "qos_incompatible": "a peer whose QoS cannot match the route's (nothing passes between them; the log says the fix)",
    "idle_skipped": "not translated: no subscriber (the newest per channel goes out when one comes)",
    "stale": "older than max_age_ms when it would be sent",
    "not_allowed": "a command channel --allow-commands does not name",
    "unknown_type": "no known LCM type (--lcm-types names the folder of its .lcm files)",
    "refused_type": "a type ROS 2 cannot express",
    "waiting_for_build": "its ROS 2 interface is being built",
    "own_message": "the bridge's own message, come back",
    "too_many_streams": "past the route's max_streams",
    "name_collision": "its channel makes the ROS name another channel has (a-b after a.b): not carried",
    "too_many_channels": "past the 10,000 channels that have ROS names, one that would be renamed",
}


def is_shown(stats: RouteSnapshot) -> bool:
    """A route worth a row: it lost or failed something, or it carries traffic for a subscriber.
    Lazy routes waiting for a subscriber and routes nothing arrived on are a line each."""
    if errors_of(stats) or any(stats.get(loss, 0) for loss in LOSSES):
        return True
    return bool(stats["state"] == "active" and (stats["messages_in"] > 0 or stats["messages_out"] > 0))


def is_waiting(stats: RouteSnapshot) -> bool:
    """A lazy route that receives traffic nobody subscribes to (and lost nothing)."""
    return not is_shown(stats) and stats["state"] != "active"


def waiting_line(
    routes: dict[str, RouteSnapshot], names: list[str], rates: dict[str, tuple[float, float]]
) -> str:
    """The routes waiting for a subscriber, each with its in-rate and what it did not translate."""
    each = (
        f"{name} in {rates[name][0]:.1f}/s (idle_skipped {routes[name]['idle_skipped']})" for name in names
    )
    return f"waiting for a subscriber: {', '.join(each)}"


def idle_state(stats: RouteSnapshot) -> str:
    """Why a lazy route sends nothing, as its line says it: `idle: no subscriber, idle_skipped 218`."""
    return f"{stats['state']}, idle_skipped {stats['idle_skipped']}"


def quiet_line(routes: dict[str, RouteSnapshot], names: list[str], listed: bool) -> str:
    """The routes nothing arrived on, counted (and named when `listed`)."""
    more = "more " if len(names) < len(routes) else ""  # beside the other lines, or all of them
    return f"{counted(len(names), more + 'route')} without traffic" + (
        f": {', '.join(names)}" if listed else ""
    )


def _terms_meanings(terms: Iterable[str]) -> list[tuple[str, str]]:
    """`(term, meaning)` of each of `terms` (counters of `LEGEND`), in its order."""
    wanted = set(terms)
    return [(term, meaning) for term, meaning in LEGEND.items() if term in wanted]


def _meanings(terms: Iterable[str]) -> list[str]:
    """`term: meaning` of each of `terms` (counters of `LEGEND`), in its order."""
    return [f"{term}: {meaning}" for term, meaning in _terms_meanings(terms)]


def legend(terms: Iterable[str]) -> str | None:
    """One line explaining `terms`; None for none."""
    said = _meanings(terms)
    return "legend: " + "; ".join(said) if said else None


def legend_lines(terms: Iterable[str], width: int | None = None) -> list[str]:
    """The legend as the table shows it: a counter a line, aligned under the first (one line of
    several wrapped at the terminal's width was hard to read): `legend: superseded: ...`,
    `        idle_skipped: ...`. A meaning longer than `width` columns goes on under itself."""
    pad = " " * len("legend: ")
    lines = []
    for index, (term, meaning) in enumerate(_terms_meanings(terms)):
        first = ("legend: " if index == 0 else pad) + f"{term}: "
        if width is None:
            lines.append(first + meaning)
        else:  # at least 20 columns of meaning on a line, however narrow the terminal
            lines.extend(textwrap.wrap(meaning, max(width, len(first) + 20), initial_indent=first,
                                       subsequent_indent=" " * len(first), break_on_hyphens=False))  # fmt: skip
    return lines


def terms_of(routes: dict[str, RouteSnapshot]) -> list[str]:
    """The counters a view of `routes` shows that a legend explains."""
    terms: set[str] = {
        loss for stats in routes.values() if is_shown(stats) for loss in LOSSES if stats.get(loss, 0)
    }
    terms |= {kind for stats in routes.values() for kinds in stats.get("held", {}).values() for kind in kinds}
    if any(is_waiting(stats) for stats in routes.values()):
        terms.add("idle_skipped")
    return sorted(terms)


class Rates:
    """Messages in and out per second of each route, since the previous snapshot (`clock`: the
    seconds they are measured in)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._previous: dict[str, tuple[int, int]] = {}  # route -> (in, out) at the last snapshot
        self._previous_at = clock()
        self.elapsed = 0.0

    def of(self, routes: dict[str, RouteSnapshot]) -> dict[str, tuple[float, float]]:
        now = self._clock()
        self.elapsed, self._previous_at = max(now - self._previous_at, 1e-9), now
        rates = {}
        for name, stats in routes.items():
            now_in, now_out = stats["messages_in"], stats["messages_out"]
            before_in, before_out = self._previous.get(name, (0, 0))
            self._previous[name] = (now_in, now_out)
            rates[name] = (now_in - before_in) / self.elapsed, (now_out - before_out) / self.elapsed
        return rates


def losses_of(stats: RouteSnapshot) -> str:
    """A route's losses in words, those that are not 0: ` superseded 5 unsent 2`."""
    return "".join(f" {loss} {stats[loss]}" for loss in LOSSES if stats.get(loss, 0))


class LogLines:
    """Each period, a log line per route that carries traffic or lost something, one for the
    routes waiting for a subscriber, one counting the routes with no traffic, one for the
    transports' own errors, and a legend of the counters not explained yet in this run: what a
    log or CI needs, not 30 idle lines."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._rates = Rates(clock)
        self._explained: set[str] = set()  # legend terms said already

    def show(self, snapshot: Snapshot) -> None:
        routes = snapshot["routes"]
        rates = self._rates.of(routes)
        for name, stats in routes.items():
            if not is_shown(stats):
                continue
            latency = stats["latency_ms"]
            log.info(
                "route %s: in %d out %d errors %d%s%s latency p50 %s p99 %s ms%s%s",
                name,
                stats["messages_in"],
                stats["messages_out"],
                errors_of(stats),
                f" warnings {warnings_of(stats)}" if stats["warnings"] else "",
                losses_of(stats),
                _ms(latency["p50"]),
                _ms(latency["p99"]),
                f" ({idle_state(stats)})" if stats["state"] != "active" else "",
                f" held: {held}" if (held := held_of(stats)) else "",
            )
        if waiting := [name for name, stats in routes.items() if is_waiting(stats)]:
            log.info("%s", waiting_line(routes, waiting, rates))
        if quiet := [name for name, stats in routes.items() if not is_shown(stats) and not is_waiting(stats)]:
            log.info("%s", quiet_line(routes, quiet, listed=False))
        if snapshot["transports"]:
            log.info("transport errors: %s", transports_line(snapshot["transports"]))
        if said := legend(term for term in terms_of(routes) if term not in self._explained):
            log.info("%s", said)
            self._explained.update(terms_of(routes))

    def close(self) -> None:
        pass


# The table's columns: (heading, what a row shows). Columns of counts that are 0 in every row are
# left out; if the rest is still wider than the terminal, OPTIONAL columns go, in this order, so
# that no number is ever cut (only a route's name may be shortened, with an ellipsis).
Cell = Callable[[RouteSnapshot, tuple[float, float]], str]
COLUMNS: dict[str, Cell] = {
    "route": lambda stats, rates: "",  # filled in with the name
    "in/s": lambda stats, rates: f"{rates[0]:.1f}",
    "out/s": lambda stats, rates: f"{rates[1]:.1f}",
    "in": lambda stats, rates: str(stats["messages_in"]),
    "out": lambda stats, rates: str(stats["messages_out"]),
    "err": lambda stats, rates: str(errors_of(stats)),
    "warn": lambda stats, rates: str(warnings_of(stats)),
    "superseded": lambda stats, rates: str(stats.get("superseded", 0)),
    "mailbox_full": lambda stats, rates: str(stats.get("mailbox_full", 0)),
    "max_hz_skipped": lambda stats, rates: str(stats.get("max_hz_skipped", 0)),
    "unsent": lambda stats, rates: str(unsent_of(stats)),
    "qos_incompatible": lambda stats, rates: str(stats.get("qos_incompatible", 0)),
    "p50": lambda stats, rates: _ms(stats["latency_ms"]["p50"]),
    "p99": lambda stats, rates: _ms(stats["latency_ms"]["p99"]),
    # why a row sends nothing, as the logged line says it (`idle: no subscriber`): heading and cell
    "idle": lambda stats, rates: "" if stats["state"] == "active" else stats["state"].removeprefix("idle: "),
}
ZERO_HIDDEN = ("warn", *LOSSES, "idle")  # shown only when some row has one (not 0, not empty)
TEXT = ("route", "idle")  # left-aligned
OPTIONAL = ("p99", "in", "out", "p50")  # dropped first when the terminal is narrow
ROUTE_MIN = 12  # characters of a route's name kept, at least, when the terminal is narrow
STYLES = {
    "err": "bold red",
    "warn": "yellow",
    "superseded": "yellow",
    "mailbox_full": "yellow",
    "unsent": "bold red",
    "qos_incompatible": "bold red",
}


class ConsoleLog(logging.Handler):
    """Log records on the console above the live table, each one line that the terminal wraps
    (soft wrap): rich inserts no line break, so a URL stays one token to copy."""

    def __init__(self, console: Console) -> None:
        super().__init__()
        self._console = console
        self.setFormatter(logging.Formatter("%(asctime)s %(message)s", datefmt="%H:%M:%S"))

    def emit(self, record: logging.LogRecord) -> None:
        style = (
            "bold red"
            if record.levelno >= logging.ERROR
            else "yellow"
            if record.levelno >= logging.WARNING
            else ""
        )
        try:
            self._console.print(Text(self.format(record), style=style), soft_wrap=True)
        except Exception:  # a log record must never stop the bridge
            self.handleError(record)


class LiveTable:
    """A table redrawn in place on the console, with log records printed above it."""

    def __init__(self, console: Console, clock: Callable[[], float] = time.monotonic) -> None:
        self._console = console
        self._live = Live(Text("starting routes ..."), console=console, auto_refresh=False, transient=False)
        self._live.start()
        self._rates = Rates(clock)

    def show(self, snapshot: Snapshot) -> None:
        routes = snapshot["routes"]
        rates = self._rates.of(routes)
        shown = [name for name, stats in routes.items() if is_shown(stats)]
        title = (f"viewer-bridge: {counted(len(routes), 'route')} "
                 f"(rates over the last {self._rates.elapsed:.1f} s; latency in ms)")  # fmt: skip
        # the title a line of its own: as the table's title it wrapped at the table's width
        parts: list[Any] = [Text(title), self._table({name: routes[name] for name in shown}, rates)]
        if waiting := [name for name, stats in routes.items() if is_waiting(stats)]:
            parts.append(Text(waiting_line(routes, waiting, rates)))
        if quiet := [name for name in routes if name not in shown and name not in waiting]:
            parts.append(Text(quiet_line(routes, quiet, listed=True), style="dim"))
        for name, stats in routes.items():
            if held := held_of(stats):
                parts.append(Text(f"{name} held back: {held}", style="yellow"))
        if snapshot["transports"]:
            parts.append(Text(f"transport errors: {transports_line(snapshot['transports'])}", style="red"))
        parts.extend(Text(line, style="dim") for line in legend_lines(terms_of(routes), self._console.width))
        self._live.update(Group(*parts), refresh=True)

    def _table(self, routes: dict[str, RouteSnapshot], rates: dict[str, tuple[float, float]]) -> Table:
        cells = {
            heading: [
                name if heading == "route" else cell(stats, rates[name]) for name, stats in routes.items()
            ]
            for heading, cell in COLUMNS.items()
        }
        headings = [h for h in COLUMNS if h not in ZERO_HIDDEN or any(v not in ("0", "") for v in cells[h])]
        widths = {h: max([len(h), *(len(value) for value in cells[h])]) for h in headings}
        widths["route"] = min(widths["route"], max(ROUTE_MIN, len("route")))  # what may shrink
        for optional in OPTIONAL:  # a column takes its width, a space either side and a rule
            if sum(widths[h] + 3 for h in headings) + 1 <= self._console.width:
                break
            headings.remove(optional)
        # The route's name gets what the numbers leave (rich crops a table that does not fit).
        names = self._console.width - 4 - sum(widths[h] + 3 for h in headings if h != "route")
        table = Table(expand=False)
        for heading in headings:
            if heading == "route":
                table.add_column(heading, no_wrap=True, overflow="ellipsis", max_width=max(ROUTE_MIN, names))
            else:  # a number (or why idle) is never cut: its column is as wide as its widest value
                table.add_column(
                    heading,
                    justify="left" if heading in TEXT else "right",
                    no_wrap=True,
                    min_width=widths[heading],
                )
        for row in range(len(routes)):
            values = [cells[heading][row] for heading in headings]
            table.add_row(*(
                Text(value, style=STYLES.get(heading, "") if value != "0" else "")
                for heading, value in zip(headings, values, strict=True)
            ))  # fmt: skip
        return table

    def close(self) -> None:
        self._live.stop()
