"""How `viewer-bridge run` shows its routes: a live table on a terminal, log lines elsewhere.

The router hands a view a snapshot of every route's counters once per stats period
(`Router.snapshot`); the view alone decides how it looks. On a terminal, `LiveTable` keeps one
table on screen, a row per route that carries traffic or has a subscriber, with rates per second
since the last snapshot, and folds the quiet routes into one line. Logs, CI and pipes get
`LogLines`: one plain line per route, the same text every period, easy to grep.
"""

from __future__ import annotations

import logging
import time
from typing import Any, Protocol

from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

log = logging.getLogger("viewer_bridge")

Snapshot = dict[str, Any]  # route name -> its stats (`RouteStats.snapshot`); "transports" -> errors


class StatusView(Protocol):
    def show(self, snapshot: Snapshot) -> None:
        """The routes' counters now (called once per stats period, and once at the end)."""

    def close(self) -> None:
        """The bridge is stopping: leave the last state on screen."""


def counted(count: int, noun: str) -> str:
    """`1 route`, `2 routes`: a count and its noun, singular or plural."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def routes_of(snapshot: Snapshot) -> dict[str, dict[str, Any]]:
    return {name: stats for name, stats in snapshot.items() if name != "transports"}


def errors_of(stats: dict[str, Any]) -> int:
    return sum(stats["errors"].values())


def warnings_of(stats: dict[str, Any]) -> int:
    """What a route left out but carried on with (a geometry a target cannot draw, say)."""
    return sum(stats["warnings"].values())


def held_of(stats: dict[str, Any]) -> str:
    """Messages held back on purpose, by kind with their channels: `unknown_type 12 (FOO, BAR)`."""
    kinds: dict[str, tuple[int, list[str]]] = {}
    for channel, counts in stats.get("held", {}).items():
        for kind, count in counts.items():
            total, channels = kinds.get(kind, (0, []))
            kinds[kind] = (total + count, [*channels, channel])
    return ", ".join(f"{kind} {total} ({', '.join(channels)})" for kind, (total, channels) in kinds.items())


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


class LogLines:
    """One log line per route (and one for the transports' own errors) each period."""

    def show(self, snapshot: Snapshot) -> None:
        for name, stats in routes_of(snapshot).items():
            latency = stats["latency_ms"]
            log.info(
                "route %s: in %d out %d errors %d%s dropped %d%s latency p50 %s p99 %s ms%s%s",
                name,
                stats["messages_in"],
                stats["messages_out"],
                errors_of(stats),
                f" warnings {warnings_of(stats)}" if stats["warnings"] else "",
                stats["dropped"],
                f" max_hz skipped {stats['max_hz_skipped']}" if stats["max_hz_skipped"] else "",
                _ms(latency["p50"]),
                _ms(latency["p99"]),
                f" ({stats['state']}, {stats['idle_skipped']} not translated)" if stats["state"] != "active" else "",
                f" held: {held}" if (held := held_of(stats)) else "",
            )
        if "transports" in snapshot:
            log.info("transports: %s", snapshot["transports"])

    def close(self) -> None:
        pass


def is_shown(stats: dict[str, Any]) -> bool:
    """A route worth a row: it lost or failed something, or it carries traffic (a lazy route:
    for a subscriber). Idle lazy routes and routes nothing arrived on are folded into a line."""
    if errors_of(stats) or stats["dropped"]:
        return True
    return bool(stats["state"] == "active" and (stats["messages_in"] > 0 or stats["messages_out"] > 0))


class LiveTable:
    """A table redrawn in place on the console, with log records printed above it."""

    def __init__(self, console: Console) -> None:
        self._console = console
        self._live = Live(Text("starting routes ..."), console=console, auto_refresh=False, transient=False)
        self._live.start()
        self._previous: dict[str, tuple[int, int]] = {}  # route -> (in, out) at the last snapshot
        self._previous_at = time.monotonic()

    def show(self, snapshot: Snapshot) -> None:
        now = time.monotonic()
        elapsed, self._previous_at = max(now - self._previous_at, 1e-9), now
        routes = routes_of(snapshot)
        rates = {name: self._rates(name, stats, elapsed) for name, stats in routes.items()}
        shown = [name for name, stats in routes.items() if is_shown(stats)]
        title = f"viewer-bridge: {counted(len(routes), 'route')} (rates over the last {elapsed:.1f} s)"
        parts: list[Any] = [self._table(title, {name: routes[name] for name in shown}, rates)]
        quiet = [name for name in routes if name not in shown]
        if quiet:
            idle = sum(1 for name in quiet if routes[name]["state"] != "active")
            parts.append(Text(f"{counted(len(quiet), 'more route')} quiet ({idle} idle: no subscriber; "
                              f"{len(quiet) - idle} without traffic): {', '.join(quiet)}", style="dim"))  # fmt: skip
        for name, stats in routes.items():
            if held := held_of(stats):
                parts.append(Text(f"{name} held back: {held}", style="yellow"))
        if "transports" in snapshot:
            parts.append(Text(f"transport errors: {snapshot['transports']}", style="red"))
        self._live.update(Group(*parts), refresh=True)

    def _rates(self, name: str, stats: dict[str, Any], elapsed: float) -> tuple[float, float]:
        now_in, now_out = stats["messages_in"], stats["messages_out"]
        before_in, before_out = self._previous.get(name, (0, 0))
        self._previous[name] = (now_in, now_out)
        return (now_in - before_in) / elapsed, (now_out - before_out) / elapsed

    @staticmethod
    def _table(title: str, routes: dict[str, dict[str, Any]], rates: dict[str, tuple[float, float]]) -> Table:
        table = Table(title=title, title_justify="left", expand=False)
        for heading in ("route", "in/s", "out/s", "in", "out", "errors", "warnings", "dropped", "p50 ms", "p99 ms"):
            table.add_column(heading, justify="left" if heading == "route" else "right", no_wrap=True)
        for name, stats in routes.items():
            rate_in, rate_out = rates[name]
            latency = stats["latency_ms"]
            errors, warnings, dropped = errors_of(stats), warnings_of(stats), stats["dropped"]
            table.add_row(
                name,
                f"{rate_in:.1f}",
                f"{rate_out:.1f}",
                str(stats["messages_in"]),
                str(stats["messages_out"]),
                Text(str(errors), style="bold red" if errors else ""),
                Text(str(warnings), style="yellow" if warnings else ""),
                Text(str(dropped), style="yellow" if dropped else ""),
                _ms(latency["p50"]),
                _ms(latency["p99"]),
            )
        return table

    def close(self) -> None:
        self._live.stop()


__all__ = [
    "LiveTable",
    "LogLines",
    "Snapshot",
    "StatusView",
    "errors_of",
    "is_shown",
    "log",
    "routes_of",
    "warnings_of",
]
