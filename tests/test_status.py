"""How `run` shows its routes: a live table on a terminal, plain lines elsewhere, nothing with --quiet."""

from __future__ import annotations

import io
import os
import pty
import re
import select
import subprocess
import sys
import time
from typing import Any

from rich.console import Console

from tests.conftest import lcm_url
from viewer_bridge.status import LiveTable, LogLines


def route(messages_in: int, messages_out: int, state: str = "active", **counts: Any) -> dict[str, Any]:
    no_samples = {"p50": None, "p99": None, "max": None}
    return {
        "state": state, "messages_in": messages_in, "messages_out": messages_out, "bytes_in": 0, "bytes_out": 0,
        "idle_skipped": counts.get("idle_skipped", 0), "errors": counts.get("errors", {}),
        "warnings": counts.get("warnings", {}), "dropped": counts.get("dropped", 0),
        "max_hz_skipped": counts.get("max_hz_skipped", 0), "queued": 0, "translate_ms": no_samples,
        "latency_ms": counts.get("latency_ms", no_samples),
    }  # fmt: skip


def table_cells(line: str) -> list[str]:
    """The cells of a table row as drawn (empty for any other line)."""
    return [cell.strip() for cell in line.strip().strip("│").split("│")] if line.startswith("│") else []


def test_the_table_shows_busy_routes_with_rates_and_folds_the_quiet_ones() -> None:
    out = io.StringIO()
    table = LiveTable(Console(file=out, force_terminal=True, width=200, color_system=None))
    table.show({"poses": route(0, 0), "tf": route(0, 0), "broken": route(0, 0)})
    time.sleep(0.5)
    latency = {"p50": 0.25, "p99": 1.5, "max": 2.0}
    table.show({
        "poses": route(30, 30, latency_ms=latency, warnings={"skipped_geometry": 2}),
        "tf": route(30, 0, "idle: no subscriber", idle_skipped=30),
        "broken": route(5, 0, "idle: no subscriber", errors={"DecodeError": 5}),
        "empty": route(0, 0),
        "transports": {"lcm": {"errors": {"dropped_by_kernel": 3}}},
    })  # fmt: skip
    table.close()
    last = out.getvalue().split("viewer-bridge: 4 routes")[-1]  # the last frame drawn
    rows = {cells[0]: cells[1:] for cells in map(table_cells, last.splitlines()) if cells}
    assert set(rows) == {"poses", "broken"}  # traffic, or an error even while idle
    rate_in, rate_out, total_in, total_out, errors, warnings, dropped, p50, p99 = rows["poses"]
    assert 0 < float(rate_in) == float(rate_out) <= 30 / 0.5 and (total_in, total_out) == ("30", "30")
    assert (errors, warnings, dropped, p50, p99) == ("0", "2", "0", "0.25", "1.50")
    assert rows["broken"][4] == "5"  # errors
    assert "2 more routes quiet (1 idle: no subscriber; 1 without traffic): tf, empty" in last
    assert "dropped_by_kernel" in last


def test_log_lines_are_one_per_route_with_the_transports_last(caplog: Any) -> None:
    with caplog.at_level("INFO", logger="viewer_bridge"):
        LogLines().show({
            "poses": route(3, 3, latency_ms={"p50": 0.25, "p99": 1.5, "max": 2.0}),
            "tf": route(2, 0, "idle: no subscriber", idle_skipped=2),
            "slow": route(5, 2, warnings={"skipped_geometry": 1}, max_hz_skipped=3),
            "transports": {"lcm": {"errors": {"dropped_by_kernel": 1}}},
        })  # fmt: skip
    assert [record.getMessage() for record in caplog.records] == [
        "route poses: in 3 out 3 errors 0 dropped 0 latency p50 0.25 p99 1.50 ms",
        "route tf: in 2 out 0 errors 0 dropped 0 latency p50 - p99 - ms (idle: no subscriber, 2 not translated)",
        "route slow: in 5 out 2 errors 0 warnings 1 dropped 0 max_hz skipped 3 latency p50 - p99 - ms",
        "transports: {'lcm': {'errors': {'dropped_by_kernel': 1}}}",
    ]


def run_bridge(*args: str, terminal: bool) -> tuple[int, str, str]:
    """`viewer-bridge run --demo` for a few seconds; stdout through a pseudo-terminal if asked."""
    command = [sys.executable, "-m", "viewer_bridge.cli", "run", "--demo", "--lcm-url", lcm_url(30), "--set",
               "foxglove.port=0", "--duration", "4", "--stats-period", "1", *args]  # fmt: skip
    if not terminal:
        done = subprocess.run(command, capture_output=True, text=True, timeout=180)
        return done.returncode, done.stdout, done.stderr
    controller, child = pty.openpty()
    env = {**os.environ, "COLUMNS": "160", "LINES": "50"}
    process = subprocess.Popen(command, stdout=child, stderr=subprocess.PIPE, env=env, text=True)
    os.close(child)
    shown = b""
    deadline = time.monotonic() + 180
    while process.poll() is None and time.monotonic() < deadline:
        if select.select([controller], [], [], 0.1)[0]:
            try:
                shown += os.read(controller, 65536)
            except OSError:  # the child closed its end
                break
    _, errors = process.communicate(timeout=60)
    os.close(controller)
    # What a person reads: the text without the terminal's colour and cursor sequences.
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", shown.decode(errors="replace")).replace("\r", "")
    return process.returncode, text, errors


def test_run_on_a_terminal_draws_the_table() -> None:
    code, shown, _ = run_bridge(terminal=True)
    assert code == 0
    assert "routes (rates over the last" in shown and "┃ route" in shown
    poses = [cells for cells in map(table_cells, shown.splitlines()) if cells[:1] == ["poses"]]
    assert poses and int(poses[-1][3]) > 0  # the demo's draws came in
    assert "routes running" in shown  # log records print above the table, on the same screen
    assert "route poses: in" not in shown  # no plain lines on a terminal


def test_run_without_a_terminal_prints_lines_and_quiet_prints_nothing_but_problems() -> None:
    code, _, lines = run_bridge(terminal=False)
    assert code == 0 and "route poses: in" in lines and "┃" not in lines
    code, out, quiet = run_bridge("--quiet", terminal=False)
    assert code == 0 and out == ""
    assert "route " not in quiet and "routes running" not in quiet


def test_held_messages_show_once_per_kind_with_their_channels(caplog: Any) -> None:
    """What a route held back on purpose (types unknown here, interfaces being built): a suffix of its
    log line, and a line under the table, by kind with the channels."""
    held = {"MYSTERY": {"unknown_type": 4}, "OTHER": {"unknown_type": 1}, "IIWA_STATUS": {"waiting_for_build": 7}}
    bus = {**route(12, 0), "held": held}
    with caplog.at_level("INFO", logger="viewer_bridge"):
        LogLines().show({"bus": bus})
    assert [record.getMessage() for record in caplog.records] == [
        "route bus: in 12 out 0 errors 0 dropped 0 latency p50 - p99 - ms "
        "held: unknown_type 5 (MYSTERY, OTHER), waiting_for_build 7 (IIWA_STATUS)"
    ]
    out = io.StringIO()
    table = LiveTable(Console(file=out, force_terminal=True, width=200, color_system=None))
    table.show({"bus": bus})
    table.close()
    assert "bus held back: unknown_type 5 (MYSTERY, OTHER), waiting_for_build 7 (IIWA_STATUS)" in out.getvalue()


def test_counts_are_singular_or_plural() -> None:
    from viewer_bridge.status import counted

    assert [counted(n, "route") for n in (0, 1, 2)] == ["0 routes", "1 route", "2 routes"]
