"""`viewer-bridge dump` and `viewer-bridge demo`, run as a user runs them."""

from __future__ import annotations

import json
import os
import random
import subprocess
import sys
from pathlib import Path

from bridge.lcmcodec import DRAW
from bridge.transports.lcm import LcmEvent, read_log, write_log
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


def test_a_file_that_is_not_an_lcm_log_is_refused(tmp_path: Path) -> None:
    junk = tmp_path / "random.bin"
    junk.write_bytes(random.Random(5).randbytes(10_000))
    for command in (("dump", str(junk)), ("convert", str(junk), str(tmp_path / "out.mcap"))):
        result = run(*command)
        assert result.returncode == 2, result
        assert f"{junk} is not an LCM log" in result.stderr and "eda1da01" in result.stderr
    assert not (tmp_path / "out.mcap").exists()  # nothing written for a file that is no log


def test_a_log_cut_short_is_read_to_its_last_whole_event_with_a_warning(drake_log: Path, tmp_path: Path) -> None:
    events = list(read_log(drake_log))
    all_but_last = tmp_path / "all_but_last.lcmlog"
    write_log(all_but_last, events[:-1])
    torn = tmp_path / "torn.lcmlog"
    write_log(torn, events)
    torn.write_bytes(torn.read_bytes()[:-37])  # the last event loses its end, as when a logger is killed
    result = run("dump", str(torn), "--json")
    assert result.returncode == 0, result.stderr
    assert len(result.stdout.splitlines()) == len(events) - 1  # every whole event
    whole = all_but_last.stat().st_size
    tail = torn.stat().st_size - whole
    assert f"{torn} ends in a partial event: the {tail} bytes after byte {whole} are not a whole event" in result.stderr


def test_run_without_the_ros_extra_names_the_install_that_fixes_it() -> None:
    # As `pip install viewer-bridge` without `[ros]`: rclpy cannot be imported.
    code = "import sys; sys.modules['rclpy'] = None; from bridge.cli import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run(
        [sys.executable, "-c", code, "run", "--duration", "1", "--set", "foxglove.port=0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    assert "the ros transport needs rclpy" in result.stderr and "pip install 'viewer-bridge[ros]'" in result.stderr
    assert "Traceback" not in result.stderr
