"""How `run` shows its routes: a live table on a terminal, plain lines elsewhere, nothing with --quiet."""

from __future__ import annotations

import io
import logging
import os
import pty
import re
import select
import socket
import subprocess
import sys
import time
from typing import Any

from rich.console import Console

from tests.conftest import lcm_url
from viewer_bridge.router.status import LEGEND, STATS_SCHEMA, ConsoleLog, LiveTable, LogLines, Snapshot


def route(messages_in: int, messages_out: int, state: str = "active", **counts: Any) -> dict[str, Any]:
    no_samples = {"p50": None, "p99": None, "max": None}
    return {
        "state": state, "messages_in": messages_in, "messages_out": messages_out, "bytes_in": 0, "bytes_out": 0,
        "idle_skipped": counts.get("idle_skipped", 0), "errors": counts.get("errors", {}),
        "warnings": counts.get("warnings", {}), "superseded": counts.get("superseded", 0),
        "mailbox_full": counts.get("mailbox_full", 0),
        "dropped": counts.get("superseded", 0) + counts.get("mailbox_full", 0),
        "max_hz_skipped": counts.get("max_hz_skipped", 0), "queued": 0, "translate_ms": no_samples,
        "latency_ms": counts.get("latency_ms", no_samples), "unsent": counts.get("unsent", 0),
    }  # fmt: skip


def snapshot(routes: dict[str, Any]) -> Snapshot:
    """The snapshot of `routes` by name ("transports": the transports' error counts)."""
    transports = routes.pop("transports", {})
    return {"schema": STATS_SCHEMA, "routes": routes, "transports": transports}


def table_cells(line: str) -> list[str]:
    """The cells of a table row as drawn (empty for any other line)."""
    return [cell.strip() for cell in line.strip().strip("│").split("│")] if line.startswith("│") else []


def test_the_table_shows_busy_routes_with_rates_and_folds_the_quiet_ones() -> None:
    out, now = io.StringIO(), [0.0]
    table = LiveTable(Console(file=out, force_terminal=True, width=200, color_system=None), lambda: now[0])
    table.show(snapshot({"poses": route(0, 0), "tf": route(0, 0), "broken": route(0, 0)}))
    now[0] += 0.5
    latency = {"p50": 0.25, "p99": 1.5, "max": 2.0}
    table.show(snapshot({
        "poses": route(30, 30, latency_ms=latency, warnings={"skipped_geometry": 2}),
        "tf": route(30, 0, "idle: no subscriber", idle_skipped=30),
        "broken": route(5, 0, "idle: no subscriber", errors={"DecodeError": 5}),
        "empty": route(0, 0),
        "transports": {"lcm": {"errors": {"dropped_by_kernel": 3}}},
    }))  # fmt: skip
    table.close()
    last = out.getvalue().split("viewer-bridge: 4 routes")[-1]  # the last frame drawn
    lines = last.splitlines()
    headings = next(cells for cells in (line.strip("┃ ").split("┃") for line in lines if "┃" in line))
    # Columns of counts that are 0 in every row (drop, unsent) are left out.
    assert [h.strip() for h in headings] == [
        "route",
        "in/s",
        "out/s",
        "in",
        "out",
        "err",
        "warn",
        "p50",
        "p99",
        "idle",
    ]
    rows = {cells[0]: cells[1:] for cells in map(table_cells, lines) if cells}
    assert set(rows) == {"poses", "broken"}  # traffic, or an error even while idle
    rate_in, rate_out, total_in, total_out, errors, warnings, p50, p99, idle = rows["poses"]
    assert idle == ""
    assert (rate_in, rate_out, total_in, total_out) == ("60.0", "60.0", "30", "30")  # 30 in half a second
    assert (errors, warnings, p50, p99) == ("0", "2", "0.25", "1.50")
    assert rows["broken"][4] == "5"  # errors
    # A lazy route with traffic and no subscriber: its in-rate, on a line of its own, not folded.
    assert "waiting for a subscriber: tf in 60.0/s (idle_skipped 30)" in last
    assert "1 more route without traffic: empty" in last
    # A row of a route that sends nothing says why in its own row, in the piped line's words
    # (`idle: no subscriber`: the column's heading and the row's cell).
    assert rows["broken"][-1] == "no subscriber"
    assert "transport errors: lcm: 3 dropped by kernel" in last  # words, not a dict
    legend = next(line for line in lines if line.startswith("legend: "))
    assert legend.startswith("legend: idle_skipped: not translated: no subscriber"), legend


def test_at_80_columns_every_number_is_whole_and_unsent_shows_in_the_row() -> None:
    """An 80-column terminal: columns go (p99 first) and long route names are shortened before any
    number would be cut; a route whose transport could not send shows it in its own row."""
    out, now = io.StringIO(), [0.0]
    table = LiveTable(Console(file=out, force_terminal=True, width=80, color_system=None), lambda: now[0])
    busy = {"p50": 1234.5, "p99": 98765.25, "max": 1e5}
    now[0] += 0.5  # rates per second over half a second
    table.show(snapshot({
        "foxglove_camera_images_unnamed": route(12345678, 1234567, latency_ms=busy, superseded=4567,
                                                warnings={"skipped_geometry": 89}, errors={"DecodeError": 123456}),
        "poses": route(468, 357, unsent=357, latency_ms=busy),
    }))  # fmt: skip
    table.close()
    lines = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", out.getvalue()).splitlines()  # without cursor moves
    assert max(map(len, lines)) <= 80, "\n".join(lines)
    rows = {cells[0]: cells[1:] for cells in map(table_cells, lines) if cells}
    assert "poses" in rows, "\n".join(lines)
    long_name = next(name for name in rows if name != "poses")
    assert long_name.endswith("…") and "foxglove_camera_images_unnamed".startswith(long_name[:-1])
    # err, warn, superseded: never dropped (p99, in, out, p50 go first)
    for number in ("123456", "89", "4567"):
        assert number in rows[long_name], (number, rows[long_name])
    assert "357" in rows["poses"]  # unsent, in the route's own row
    every_cell = [cell for cells in rows.values() for cell in cells]
    assert all(re.fullmatch(r"\d+(\.\d+)?|-", cell) for cell in every_cell), "\n".join(lines)


def test_at_100_columns_idle_rows_say_why_and_the_title_is_one_line() -> None:
    """The demo's table on a 100x30 terminal: busy rows and rows of lazy routes that lost draws
    while nobody subscribed; each idle row says why in its own cell, no number is cut."""
    out, now = io.StringIO(), [0.0]
    table = LiveTable(Console(file=out, force_terminal=True, width=100, color_system=None), lambda: now[0])
    latency = {"p50": 0.37, "p99": 1.61, "max": 2.0}
    idle = {"superseded": 58, "idle_skipped": 246}
    now[0] += 0.5  # rates per second over half a second
    table.show(snapshot({
        "tf": route(304, 0, "idle: no subscriber", **idle),
        "foxglove_transforms": route(300, 0, "idle: no subscriber", **idle),
        "poses": route(300, 242, superseded=58, latency_ms=latency),
        "shapes": route(4, 9, latency_ms={"p50": 137.23, "p99": 137.23, "max": 137.23}),
        "lcm_in": route(0, 0),
    }))  # fmt: skip
    table.close()
    lines = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", out.getvalue()).splitlines()
    assert max(map(len, lines)) <= 100, "\n".join(lines)
    assert any(line.startswith("viewer-bridge: 5 routes (rates over the last ") and line.endswith("latency in ms)")
               for line in lines), "\n".join(lines)  # fmt: skip
    headings = next(cells for cells in (line.strip("┃ ").split("┃") for line in lines if "┃" in line))
    assert [h.strip() for h in headings][-1] == "idle"
    rows = {cells[0]: cells[1:] for cells in map(table_cells, lines) if cells}
    long_name = next(name for name in rows if name.startswith("foxglove_"))  # shortened, maybe
    assert rows["tf"][-1] == rows[long_name][-1] == "no subscriber", "\n".join(lines)
    assert rows["poses"][-1] == rows["shapes"][-1] == ""
    assert "304" in rows["tf"] and "58" in rows["tf"] and "137.23" in rows["shapes"]
    assert (
        "legend: superseded: a newer message on its channel came first (policy latest: the newest is sent)"
        in lines
    )


def test_at_100_columns_every_legend_line_fits_and_a_long_meaning_goes_on_under_itself() -> None:
    """The longest meanings (unsent, qos_incompatible, name_collision) wrap in the legend's
    indentation, not at the terminal's edge."""
    out, now = io.StringIO(), [0.0]
    table = LiveTable(Console(file=out, force_terminal=True, width=100, color_system=None), lambda: now[0])
    now[0] += 0.5
    table.show(snapshot({
        "poses": route(300, 242, superseded=58),
        "zenoh_poses": {**route(9, 9, unsent=9), "qos_incompatible": 1},
        "lcm_bus": {**route(12, 0), "held": {"a-b": {"name_collision": 12}}},
    }))  # fmt: skip
    table.close()
    lines = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", out.getvalue()).splitlines()
    assert max(map(len, lines)) <= 100, "\n".join(lines)
    # the longest meanings go on under themselves, in the legend's indentation
    last = max(i for i, line in enumerate(lines) if line.startswith("legend: "))  # the last drawing's
    legend = [line for line in lines[last:] if line.strip()]
    assert all(line.startswith(" " * len("legend: ")) for line in legend[1:]), "\n".join(legend)
    told = " ".join(line.strip() for line in legend)
    for term in ("superseded", "unsent", "qos_incompatible", "name_collision"):
        assert f"{term}: {LEGEND[term]}" in told, "\n".join(legend)


def test_at_80_columns_a_busy_demo_keeps_its_totals() -> None:
    out, now = io.StringIO(), [0.0]
    table = LiveTable(Console(file=out, force_terminal=True, width=80, color_system=None), lambda: now[0])
    latency = {"p50": 0.29, "p99": 148.25, "max": 150.0}
    table.show(snapshot({"foxglove_transforms": route(46770, 46770), "poses": route(46770, 46769)}))
    now[0] += 0.5  # then 30 more: 60 a second, as the demo sends
    table.show(snapshot({"foxglove_transforms": route(46800, 46800, latency_ms=latency, mailbox_full=5),
                "poses": route(46800, 46799, latency_ms=latency)}))  # fmt: skip
    table.close()
    lines = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", out.getvalue()).splitlines()
    last = lines[max(i for i, line in enumerate(lines) if "┃ route" in line) :]
    assert max(map(len, last)) <= 80
    assert [h.strip() for h in last[0].strip("┃").split("┃")] == [
        "route",
        "in/s",
        "out/s",
        "in",
        "out",
        "err",
        "mailbox_full",
        "p50",
    ]  # fmt: skip  (p99 goes first, for the counter's long name)
    rows = {cells[0]: cells[1:] for cells in map(table_cells, last) if cells}
    foxglove = next(cells for name, cells in rows.items() if name.startswith("foxglove_tr"))
    assert foxglove[:6] == ["60.0", "60.0", "46800", "46800", "0", "5"] and rows["poses"][3] == "46799"
    assert all(re.fullmatch(r"\d+(\.\d+)?|-", cell) for cells in rows.values() for cell in cells)
    assert any(
        line.startswith("legend: mailbox_full: the oldest waiting message pushed out") for line in last
    )


def test_log_lines_show_routes_with_traffic_and_count_the_rest(caplog: Any) -> None:
    with caplog.at_level("INFO", logger="viewer_bridge"):
        LogLines(iter([0.0, 0.5]).__next__).show(snapshot({  # half a second after the view was made
            "poses": route(3, 3, latency_ms={"p50": 0.25, "p99": 1.5, "max": 2.0}),
            "tf": route(2, 0, "idle: no subscriber", idle_skipped=2),
            "slow": route(5, 2, warnings={"skipped_geometry": 1}, max_hz_skipped=3, superseded=1),
            "zenoh_poses": route(4, 4, unsent=4),
            "empty": route(0, 0),
            "transports": {"zenoh": {"errors": {"unsent_no_router": 4}}},
        }))  # fmt: skip
    assert [record.getMessage() for record in caplog.records] == [
        "route poses: in 3 out 3 errors 0 latency p50 0.25 p99 1.50 ms",
        "route slow: in 5 out 2 errors 0 warnings 1 superseded 1 max_hz_skipped 3 latency p50 - p99 - ms",
        "route zenoh_poses: in 4 out 4 errors 0 unsent 4 latency p50 - p99 - ms",
        "waiting for a subscriber: tf in 4.0/s (idle_skipped 2)",
        "1 more route without traffic",
        "transport errors: zenoh: 4 unsent no router",
        "legend: superseded: a newer message on its channel came first (policy latest: the newest is sent); "
        "max_hz_skipped: superseded while the route waited out its rate.max_hz (by design); "
        "unsent: given to a transport that could not send it (a Zenoh session with no router, no Rerun viewer); "
        "idle_skipped: not translated: no subscriber (the newest per channel goes out when one comes)",
    ]


def test_log_lines_explain_each_counter_once(caplog: Any) -> None:
    """The legend after the lines names only counters not explained yet: a log is not repeated."""
    lines = LogLines()
    with caplog.at_level("INFO", logger="viewer_bridge"):
        lines.show(snapshot({"poses": route(3, 3, mailbox_full=1)}))
        lines.show(snapshot({"poses": route(6, 6, mailbox_full=2)}))
        lines.show(
            snapshot(
                {"poses": route(9, 9, mailbox_full=2), "cmd": {**route(1, 0), "held": {"X": {"stale": 1}}}}
            )
        )
    said = [record.getMessage() for record in caplog.records if record.getMessage().startswith("legend: ")]
    assert said == [
        "legend: mailbox_full: the oldest waiting message pushed out (policy all: qos.depth was full)",
        "legend: stale: older than max_age_ms when it would be sent",
    ]


def test_a_log_record_on_the_console_keeps_a_url_whole() -> None:
    """Above the live table, log records are soft-wrapped: no line break inside a URL."""
    out = io.StringIO()
    console = Console(file=out, force_terminal=True, width=80, color_system=None)
    url = "https://app.foxglove.dev?ds=foxglove-websocket&ds.url=ws%3A%2F%2F127.0.0.1%3A8765"
    ConsoleLog(console).emit(
        logging.makeLogRecord({"msg": "serving (open %s)", "args": (url,), "levelno": 20})
    )
    assert url in out.getvalue()


def run_bridge(*args: str, terminal: bool) -> tuple[int, str, str]:
    """`viewer-bridge run --demo` for a few seconds; stdout through a pseudo-terminal if asked."""
    command = [sys.executable, "-m", "viewer_bridge.cli.main", "run", "--demo", "--lcm-url", lcm_url(30), "--set",
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
    held = {
        "MYSTERY": {"unknown_type": 4},
        "OTHER": {"unknown_type": 1},
        "IIWA_STATUS": {"waiting_for_build": 7},
    }
    bus = {**route(12, 0), "held": held}
    with caplog.at_level("INFO", logger="viewer_bridge"):
        LogLines().show(snapshot({"bus": bus}))
    assert [record.getMessage() for record in caplog.records] == [
        "route bus: in 12 out 0 errors 0 latency p50 - p99 - ms "
        "held: unknown_type 5 (MYSTERY, OTHER), waiting_for_build 7 (IIWA_STATUS)",
        "legend: unknown_type: no known LCM type (--lcm-types names the folder of its .lcm files); "
        "waiting_for_build: its ROS 2 interface is being built",
    ]
    out = io.StringIO()
    table = LiveTable(Console(file=out, force_terminal=True, width=200, color_system=None))
    table.show(snapshot({"bus": bus}))
    table.close()
    assert (
        "bus held back: unknown_type 5 (MYSTERY, OTHER), waiting_for_build 7 (IIWA_STATUS)" in out.getvalue()
    )


def test_counts_are_singular_or_plural() -> None:
    from viewer_bridge.util.words import counted

    assert [counted(n, "route") for n in (0, 1, 2)] == ["0 routes", "1 route", "2 routes"]


def test_without_a_zenoh_router_the_routes_say_what_was_not_delivered() -> None:
    """`-c builtin:zenoh` with no router: the poses route's line counts what could not be sent, and
    the transport's own count is a sentence, not a dict."""
    with socket.socket() as probe:  # a port where no router listens
        probe.bind(("127.0.0.1", 0))
        nowhere = probe.getsockname()[1]
    code, _, lines = run_bridge("-c", "builtin:zenoh", "--set", f"zenoh.connect=[tcp/127.0.0.1:{nowhere}]",
                                terminal=False)  # fmt: skip
    assert code == 0, lines[-2000:]
    poses = re.findall(r"route poses: in (\d+) out (\d+) errors 0(?: superseded \d+)? unsent (\d+)", lines)
    assert poses and int(poses[-1][2]) > 0, lines[-2000:]
    assert re.search(r"transport errors: zenoh: \d+ unsent no router", lines), lines[-2000:]
    assert "{'zenoh'" not in lines


def test_a_qos_mismatch_shows_in_the_row_the_line_and_the_legend(caplog: Any) -> None:
    """A route that nothing reaches because a peer's QoS cannot match is shown, not folded into the
    routes without traffic: its count in the table's row and in the log line, explained once."""
    mismatched = {**route(0, 0), "qos_incompatible": 2}
    out = io.StringIO()
    table = LiveTable(Console(file=out, force_terminal=True, width=120, color_system=None))
    table.show(snapshot({"forced": mismatched, "idle": route(0, 0)}))
    table.close()
    drawn = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", out.getvalue()).splitlines()
    heading = next(line for line in drawn if "qos_incompatible" in line)  # rich draws it with ┃
    header = [cell.strip() for cell in heading.strip().strip("┃").split("┃")]
    rows = {cells[0]: cells for cells in map(table_cells, drawn) if cells}
    assert rows["forced"][header.index("qos_incompatible")] == "2", "\n".join(drawn)
    with caplog.at_level("INFO", logger="viewer_bridge"):
        LogLines().show(snapshot({"forced": mismatched}))
    said = [record.getMessage() for record in caplog.records]
    assert any(line.startswith("route forced:") and "qos_incompatible 2" in line for line in said), said
    assert any(line.startswith("legend: qos_incompatible: ") for line in said), said
