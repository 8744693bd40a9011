"""`viewer-bridge dump` and `viewer-bridge demo`, run as a user runs them."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from bridge.lcmcodec import DRAW
from bridge.transports.lcm import LcmEvent, write_log
from tests.conftest import lcm_url

CLI = [sys.executable, "-m", "bridge.cli"]


def run(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*CLI, *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


def test_dump_json_of_a_real_drake_log_has_every_field(drake_log: Path) -> None:
    result = run("dump", str(drake_log), "--json", "--channel", "DRAKE_VIEWER_(LOAD_ROBOT|DRAW)_ILLUSTRATION")
    assert result.returncode == 0, result.stderr
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert {r["channel"] for r in records} == {
        "DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION",
        "DRAKE_VIEWER_DRAW_ILLUSTRATION",
    }
    load = next(r for r in records if r["type"] == "drake.lcmt_viewer_load_robot")
    geometry = load["message"]["link"][1]["geom"][0]
    assert set(geometry) == {
        "type",
        "position",
        "quaternion",
        "color",
        "string_data",
        "num_float_data",
        "float_data",
    }
    draw = next(r for r in records if r["type"] == "drake.lcmt_viewer_draw")
    assert draw["fingerprint"] == "414f0bfe5b2f4244"
    assert (
        len(draw["message"]["quaternion"])
        == draw["message"]["num_links"]
        == len(draw["message"]["link_name"])
    )


def test_dump_text_reports_unknown_and_malformed_messages_and_goes_on(tmp_path: Path) -> None:
    good = DRAW.message_class(
        timestamp=7,
        num_links=1,
        link_name=["plant::a"],
        robot_num=[2],
        position=[[1.0, 2.0, 3.0]],
        quaternion=[[1.0, 0.0, 0.0, 0.0]],
    ).encode()
    log = tmp_path / "mixed.lcmlog"
    write_log(
        log,
        [
            LcmEvent("DRAKE_VIEWER_DRAW", good[:-2], 1),
            LcmEvent("OTHER", b"hello world", 2),
            LcmEvent("DRAKE_VIEWER_DRAW", good, 3),
        ],
    )
    result = run("dump", str(log))
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "drake.lcmt_viewer_draw.quaternion at byte" in out  # the truncated one, named
    assert "OTHER (unknown type)" in out
    assert "link_name: ['plant::a']" in out and "timestamp: 7" in out  # the good one after both


def test_dump_live_with_the_demo_source() -> None:
    result = run("dump", "--live", lcm_url(), "--demo", "--duration", "1.5", "--json")
    assert result.returncode == 0, result.stderr
    records = [json.loads(line) for line in result.stdout.splitlines()]
    types = {r["type"] for r in records}
    assert types == {"drake.lcmt_viewer_load_robot", "drake.lcmt_viewer_draw"}
    load = next(r for r in records if r["type"] == "drake.lcmt_viewer_load_robot")
    assert sorted({g["type"] for link in load["message"]["link"] for g in link["geom"]}) == [1, 2, 3, 4, 5, 6]
    assert sum(r["type"] == "drake.lcmt_viewer_draw" for r in records) > 20
    assert not any("error" in r for r in records)


def test_dump_needs_exactly_one_source() -> None:
    assert run("dump").returncode == 2
