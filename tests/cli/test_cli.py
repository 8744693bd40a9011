"""`viewer-bridge dump` and `viewer-bridge demo`, run as a user runs them."""

from __future__ import annotations

import json
import os
import random
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import lcm_url
from tests.translators.test_lcm_generic import CORPUS, arm_status, lcmgen_corpus  # noqa: F401 (a fixture)
from viewer_bridge.lcmcodec.codecs import DRAW
from viewer_bridge.transports.lcm import LcmEvent, read_log, write_log

CLI = [sys.executable, "-m", "viewer_bridge.cli.main"]


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
    assert (  # arrays flat and row-major, as in ROS 2's mapping: 4 numbers per link
        len(draw["message"]["quaternion"]) // 4
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


def test_a_log_cut_short_is_read_to_its_last_whole_event_with_a_warning(
    drake_log: Path, tmp_path: Path
) -> None:
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
    assert (
        f"{torn} ends in a partial event: the {tail} bytes after byte {whole} are not a whole event"
        in result.stderr
    )


def test_run_without_the_ros_extra_names_the_install_that_fixes_it() -> None:
    # As `pip install viewer-bridge` without `[ros]`: rclpy cannot be imported.
    code = "import sys; sys.modules['rclpy'] = None; from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))"
    # The built-in config: its ROS 2 routes left out in one line naming the extra, the rest runs.
    result = subprocess.run(
        [sys.executable, "-c", code, "run", "--duration", "1", "--set", "foxglove.port=0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert "the built-in config's 17 ROS 2 routes left out: they need rclpy, not installed: pip install " \
           "'viewer-bridge[ros]'" in result.stderr  # fmt: skip
    assert "Traceback" not in result.stderr
    # A config named with -c runs as written, or stops naming what it lacks.
    named = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "run",
            "-c",
            "builtin:default",
            "--duration",
            "1",
            "--set",
            "foxglove.port=0",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert named.returncode == 2, named.stderr
    assert (
        "the ros transport needs rclpy" in named.stderr and "pip install 'viewer-bridge[ros]'" in named.stderr
    )
    assert "Traceback" not in named.stderr


# A built-in translator with a bug: it raises at construction, as a plugin's might.
BUGGY = (
    "import sys; from viewer_bridge.translators.drake_ros import DrakeToPoseArray\n"
    "def broken(self, *args, **kwargs): raise ValueError('a bug in a translator')\n"
    "DrakeToPoseArray.__init__ = broken\n"
    "from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))"
)


@pytest.mark.parametrize("debug", [False, True])
def test_an_internal_error_is_said_as_a_bug_and_debug_shows_its_traceback(debug: bool) -> None:
    words = ["run", "--lcm-url", lcm_url(), "--duration", "1", *(["--debug"] if debug else [])]
    result = subprocess.run(
        [sys.executable, "-c", BUGGY, *words], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 1, result.stderr
    if debug:
        assert "Traceback (most recent call last)" in result.stderr, result.stderr
        assert "ValueError: a bug in a translator" in result.stderr.splitlines()[-1]
    else:  # never passed off as a mistake in what was given
        assert "Traceback" not in result.stderr
        assert result.stderr.splitlines()[-1] == (
            "viewer-bridge run: internal error: ValueError: a bug in a translator "
            "(a bug in viewer-bridge: --debug shows its traceback)"
        )


def test_a_user_mistake_stays_one_line_under_debug(tmp_path: Path) -> None:
    config = tmp_path / "bridge.yaml"
    config.write_text(
        "routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: teleport\n"
        "    destination: {transport: ros, name: /x}\n"
    )
    result = run("run", "-c", str(config), "--debug")
    assert result.returncode == 2 and len(result.stderr.splitlines()) == 1, result.stderr
    assert "routes.0.translator: unknown translator 'teleport'" in result.stderr


# --- convert: nothing lost ----------------------------------------------------------------------------


def demo_log(path: Path, draws: int) -> Path:
    """A log of the demo scene: its load, then `draws` draws at 60 Hz."""
    from viewer_bridge.examples.demo import demo_poses, demo_scene
    from viewer_bridge.formats.drake.draw import DrawEncoder
    from viewer_bridge.formats.drake.load import load_from_scene

    scene = demo_scene()
    encoder = DrawEncoder()
    events = [LcmEvent("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode(), 0)]
    events += [
        LcmEvent("DRAKE_VIEWER_DRAW", encoder.encode(demo_poses(scene, i / 60)), 1000 + i * 16_667)
        for i in range(draws)
    ]
    write_log(path, events)
    return path


def test_convert_never_writes_over_its_input_even_through_links(tmp_path: Path) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 10)
    before = log.read_bytes()
    symlink = tmp_path / "link.mcap"
    symlink.symlink_to(log)
    hardlink = tmp_path / "hard.mcap"
    hardlink.hardlink_to(log)
    for target in (log, symlink, hardlink):
        for force in ((), ("--force",)):
            result = run("convert", str(log), str(target), *force)
            assert result.returncode == 2, result
            assert result.stderr.startswith(f"viewer-bridge convert: {target} is the input log"), (
                result.stderr
            )
            assert "Traceback" not in result.stderr
    assert log.read_bytes() == before


def test_convert_replaces_an_existing_file_only_with_force(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    log = demo_log(tmp_path / "demo.lcmlog", 10)
    out = tmp_path / "out.mcap"
    out.write_text("keep me")
    refused = run("convert", str(log), str(out))
    assert refused.returncode == 2, refused
    assert (
        refused.stderr
        == f"viewer-bridge convert: {out} exists: give another output file, or --force to replace it\n"
    )
    assert out.read_text() == "keep me"
    forced = run("convert", str(log), str(out), "--force")
    assert forced.returncode == 0, forced.stderr
    with out.open("rb") as file:
        topics = {channel.topic for _, channel, _ in make_reader(file).iter_messages()}
    assert "/drake/poses" in topics
    assert not (tmp_path / "out.mcap.partial").exists()  # renamed once complete


def test_convert_with_no_route_for_the_schema_exits_2_naming_config_and_schema(tmp_path: Path) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 3)
    out = tmp_path / "out.mcap"
    result = run("convert", str(log), str(out), "-c", "builtin:ign")
    assert result.returncode == 2, result
    assert (
        result.stderr
        == "viewer-bridge convert: no route of builtin:ign reads LCM and writes the ros2 schema\n"
    )
    empty = tmp_path / "empty.yaml"
    empty.write_text("routes: []\n")
    result = run("convert", str(log), str(out), "-c", str(empty), "--schema", "foxglove")
    assert result.returncode == 2, result
    assert f"no route of {empty} reads LCM and writes the foxglove schema" in result.stderr
    assert not out.exists() and not (tmp_path / "out.mcap.partial").exists()


def test_ctrl_c_during_convert_leaves_a_readable_partial_file_and_exits_130(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    # Forty copies of the markers route make the conversion slow (about 30 s unloaded) from a
    # small log, so that the interrupt surely comes midway.
    routes = "".join(
        f"  - name: markers{i}\n"
        f'    source: {{transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"}}\n'
        f"    translator: drake_to_marker_array\n"
        f"    destination: {{transport: ros, name: slow/markers{i}}}\n"
        for i in range(40)
    )
    config = tmp_path / "slow.yaml"
    config.write_text(f"routes:\n{routes}")
    log = demo_log(tmp_path / "demo.lcmlog", 20_000)
    out = tmp_path / "out.mcap"
    partial = tmp_path / "out.mcap.partial"
    written = interrupted_convert([*CLI, "convert", str(log), str(out), "-c", str(config)], partial)
    with partial.open("rb") as file:
        messages = sum(1 for _ in make_reader(file).iter_messages())
    assert messages == written < 40 * 20_001
    assert not out.exists()


def test_ctrl_c_before_the_first_message_is_written_keeps_nothing_and_says_so(tmp_path: Path) -> None:
    """A `.partial` with no message in it would look like a result: the Ctrl-C removes it."""
    # Events no route writes come first (the stop is looked at between events): the interrupt
    # lands while nothing is written yet.
    log = tmp_path / "late.lcmlog"
    nobody = (LcmEvent("NOBODY_READS_THIS", b"12345678", i) for i in range(1_000_000))
    write_log(log, [*nobody, *read_log(demo_log(tmp_path / "demo.lcmlog", 10))])
    out, partial = tmp_path / "out.mcap", tmp_path / "out.mcap.partial"
    assert (
        interrupted_convert([*CLI, "convert", str(log), str(out)], partial, written_beyond=0) == 0
    )  # as soon as it is there
    assert not partial.exists() and not out.exists()


def interrupted_convert(command: list[str], partial: Path, written_beyond: int = 1 << 16) -> int:
    """Run a `convert` and Ctrl-C it once it has written `written_beyond` bytes into `partial`
    (some messages: a `.partial` with none is not kept): it exits 130, with no traceback, saying in
    one line how many messages it kept there (returned; 0: it says nothing is kept)."""
    child = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while child.poll() is None and time.monotonic() < deadline:
            if partial.exists() and partial.stat().st_size >= written_beyond:
                break
            time.sleep(0.02)
        assert partial.exists(), child.communicate(timeout=60)
        child.send_signal(signal.SIGINT)
        _, stderr = child.communicate(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 130, stderr
    said = (
        rf"^viewer-bridge convert: interrupted: "
        rf"(?:(\d+) messages written to {re.escape(str(partial))}|no message written yet: nothing kept)$"
    )
    match = re.search(said, stderr, re.M)
    assert match and "Traceback" not in stderr, stderr
    return int(match.group(1) or 0)


# --- convert: says what it did -------------------------------------------------------------------------


def test_convert_refuses_an_extension_it_does_not_write_unless_format_says(tmp_path: Path) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 3)
    bag = tmp_path / "x.bag"
    refused = run("convert", str(log), str(bag))
    assert refused.returncode == 2 and not refused.stdout, refused
    assert refused.stderr == (
        f"viewer-bridge convert: {bag}: convert writes .mcap (MCAP) or .rrd (Rerun) files: "
        "name the output so, or say which with --format mcap|rrd\n"
    )
    assert not bag.exists()
    chosen = run("convert", str(log), str(bag), "--format", "mcap")
    assert chosen.returncode == 0, chosen.stderr
    assert bag.read_bytes().startswith(b"\x89MCAP")


def test_convert_says_what_it_wrote_as_the_file_reads_back(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    log = tmp_path / "lab.lcmlog"
    # no known fingerprint
    unknown = [LcmEvent("LAB_STATUS", b"12345678abc", 2_000_000 + i) for i in range(10)]
    write_log(log, [*read_log(demo_log(tmp_path / "demo.lcmlog", 10)), *unknown])
    out = tmp_path / "out.mcap"
    result = run("convert", str(log), str(out))
    assert result.returncode == 0, result.stderr  # other messages were written
    with out.open("rb") as file:
        topics = [channel.topic for _, channel, _ in make_reader(file).iter_messages()]
    said = result.stdout.splitlines()[-1]
    assert said == f"wrote {out}: {len(topics)} messages on {len(set(topics))} topics", result.stdout
    assert len(set(topics)) > 1
    assert (
        "viewer-bridge convert: skipped: 10 messages on LAB_STATUS: "
        "unknown_type, no known LCM type (--lcm-types names the folder of its .lcm files)"
    ) in result.stderr.splitlines()


def test_convert_exits_1_when_lcm_channels_match_nothing_or_nothing_is_written(tmp_path: Path) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 3)
    out = tmp_path / "out.mcap"
    nomatch = run("convert", str(log), str(out), "--lcm-channels", "nomatch")
    assert nomatch.returncode == 1, nomatch
    assert nomatch.stderr.splitlines()[-1] == (
        "viewer-bridge convert: --lcm-channels 'nomatch' matches no channel of the log "
        "(its channels: DRAKE_VIEWER_DRAW, DRAKE_VIEWER_LOAD_ROBOT)"
    )
    # the Drake routes' topics, said first
    assert nomatch.stdout.splitlines()[-1].startswith(f"wrote {out}: ")
    lab = tmp_path / "lab.lcmlog"
    write_log(lab, [LcmEvent("LAB_STATUS", b"12345678abc", 1)])
    empty = tmp_path / "empty.mcap"
    nothing = run("convert", str(lab), str(empty))
    assert nothing.returncode == 1 and not nothing.stdout, nothing
    assert nothing.stderr.splitlines()[-1] == (
        f"viewer-bridge convert: nothing written to {empty}: every message read was skipped (said above)"
    )
    assert not empty.exists() and not empty.with_name("empty.mcap.partial").exists()


def test_an_unknown_type_is_said_once_for_the_router_and_counted_per_route(
    tmp_path: Path, caplog: Any
) -> None:
    """Two routes read a channel of no known type: one warning, and each route counts it."""
    from viewer_bridge.cli.log_convert import convert
    from viewer_bridge.config.bridge import BridgeConfig

    routes = [
        {"name": f"bus{i}", "source": {"transport": "lcm", "name": "(.*)"}, "translator": "lcm_to_ros",
         "destination": {"transport": "ros", "name": f"/copy{i}/{{1:topic}}"}}
        for i in (1, 2)
    ]  # fmt: skip
    log = tmp_path / "lab.lcmlog"
    write_log(log, [LcmEvent("LAB_STATUS", b"12345678abc", i) for i in range(4)])
    with caplog.at_level("WARNING", logger="viewer_bridge"):
        done = convert(
            log, tmp_path / "out.mcap", BridgeConfig.model_validate({"routes": routes}), progress=False
        )
    said = [
        record.getMessage() for record in caplog.records if "LAB_STATUS: fingerprint" in record.getMessage()
    ]
    assert len(said) == 1, said
    assert done.skipped == {("LAB_STATUS", "unknown_type"): 4} and not done.written


# --- one-line errors ------------------------------------------------------------------------------------

# (command words, a part of the message); LOG is a real log, MISSING a folder that does not exist.
MISTAKES = [
    (["dump", "nope.lcmlog"], "nope.lcmlog: no such file"),
    (["dump", "TMP"], "is a folder, not a file"),
    (["dump", "LOG", "--channel", "DRAKE_(VIEWER"], "'DRAKE_(VIEWER' is not a regular expression"),
    (["dump", "--live", "URL", "--channel", "DRAKE_(VIEWER"], "'DRAKE_(VIEWER' is not a regular expression"),
    (["run", "--lcm-url", "missing.lcmlog"], "argument --lcm-url: missing.lcmlog: no such file"),
    (["run", "--stats-json", "MISSING/s.json", "--duration", "30"], "the folder MISSING does not exist"),
    (["run", "--ros-args", "-r", "__ns:=/sim1", "--duration", "2"], "'--duration' is not a ROS argument"),
    (["snapshot", "nope.lcmlog", "TMP/x.png"], "nope.lcmlog: no such file"),
    (["snapshot", "LOG", "TMP/x.png", "--fov", "0"], "argument --fov: must be between 0 and 180"),
    (["snapshot", "LOG", "TMP/x.png", "--size", "0x0"], "argument --size: width and height must be 1 to"),
    (["snapshot", "LOG", "TMP/x.png", "--size", "640"], "argument --size: '640' is not WIDTHxHEIGHT"),
    (["snapshot", "LOG", "TMP/x.png", "--hide", "("], "argument --hide: '(' is not a regular expression"),
    (["snapshot", "LOG", "MISSING/x.png"], "the folder MISSING does not exist"),
    (["snapshot", "LOG", "TMP/x.gif"], "x.gif: the name must end in .png, .jpg, .jpeg"),
    (["snapshot", "LOG", "TMP/x.jpg", "--image", "depth"], "a depth image is 16-bit: write it as .png"),
    # A demo log has no contact results and no role-suffixed channels: said, with what would do.
    (["snapshot", "LOG", "TMP/x.png", "--contacts"], "(`viewer-bridge example contacts` does)"),
    (["snapshot", "LOG", "TMP/x.png", "--role", "illustration"], "(it has DRAKE_VIEWER_LOAD_ROBOT: choose with --role)"),
    (["serve-render", "--port", "70000"], "argument --port: a port is 0 (any free one) to 65535"),
    (["serve-render", "--port", "BUSY"], "cannot listen on 127.0.0.1:BUSY: Address already in use"),
    (["serve-render", "--max-requests", "0"], "argument --max-requests: '0' is not a number of requests from 1 to"),
    (["serve-render", "--max-image", "4096"], "argument --max-image: '4096' is not WIDTHxHEIGHT, each 1 to 16384"),
    (["demo", "--rate", "0"], "argument --rate: must be greater than 0"),
    (["demo", "--url", "nope://x"], "unknown LCM provider 'nope'"),
    (["convert", "nope.lcmlog", "TMP/x.mcap"], "nope.lcmlog: no such file"),
    (["convert", "LOG", "MISSING/x.mcap"], "the folder MISSING does not exist"),
    # Settings a config would refuse, or that would do nothing with it.
    (["run", "--set", "foxglove.prot=9000"], "--set foxglove.prot=9000: foxglove.prot: unknown key 'prot' "
     "(did you mean 'port'?); known keys: host, port"),
    (["run", "--set", "foxglove.port"], "--set 'foxglove.port': expected TRANSPORT.KEY=VALUE, e.g. foxglove.port=9000"),
    (["run", "--set", "ros.namespace=/sim 1"], "'/sim 1' is not a valid ROS 2 namespace"),
    (["run", "--set", "ros.node=9x"], "'9x' is not a valid ROS 2 node name: it starts with a digit"),
    # ROS arguments as rcl reads them, refused before rclpy sees them.
    (["run", "--ros-args", "-r", "__ns:=bad-ns", "--", "--duration", "2"],
     "--ros-args: -r __ns:=bad-ns: 'bad-ns' is not a valid ROS 2 namespace: it must be absolute"),
    (["run", "--ros-args", "-r", "__node:=my-node", "--", "--duration", "2"],
     "--ros-args: -r __node:=my-node: 'my-node' is not a valid ROS 2 node name"),
    (["run", "--ros-args", "-p", "use_sim_time:=maybe", "--", "--duration", "2"],
     "--ros-args: -p use_sim_time:=maybe: use_sim_time is a bool (true or false), not 'maybe'"),
    (["run", "-c", "builtin:zenoh", "--set", "zenoh.connect=[tcp/localhost:notaport]"],
     "'tcp/localhost:notaport' is not a Zenoh endpoint: the port 'notaport' is not a number from 0 to 65535"),
    (["run", "-c", "builtin:zenoh", "--set", "zenoh.listen=[localhost]"],
     "'localhost' is not a Zenoh endpoint: expected <protocol>/<address>"),
    # LCM's file provider writes a log with ?mode=w: into a folder that exists; the demo inside
    # `run` cannot feed routes through a log that is only written.
    (["demo", "--url", "file://MISSING/x.lcmlog?mode=w"], "the folder MISSING does not exist"),
    (["run", "--demo", "--lcm-url", "file://TMP/x.lcmlog?mode=w"], "--demo: the routes would read the demo on"),
    # Patterns that can never match: a ROS 2 topic without its leading /, an LCM channel with one.
    (["run", "--ros-topics", "joint_states"], "argument --ros-topics: 'joint_states' can never match a ROS 2 "
     "topic (every topic name starts with /): did you mean '/joint_states'?"),
    (["run", "--ros-topics", "/imu|^joint_states"], "'joint_states' can never match a ROS 2 topic"),
    (["run", "--allow-commands", "/lcm_in/IIWA_COMMAND"], "argument --allow-commands: '/lcm_in/IIWA_COMMAND' can "
     "never match an LCM channel (a channel is named without a leading /): did you mean 'IIWA_COMMAND'?"),
]  # fmt: skip


@pytest.mark.parametrize(("words", "said"), MISTAKES, ids=[" ".join(words) for words, _ in MISTAKES])
def test_a_mistake_is_one_line_and_exit_2(tmp_path: Path, words: list[str], said: str) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 3)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        names = {
            "LOG": str(log),
            "TMP": str(tmp_path),
            "MISSING": str(tmp_path / "missing"),
            "URL": lcm_url(),
            "BUSY": str(busy.getsockname()[1]),
        }

        def named(text: str) -> str:
            return re.sub("|".join(names), lambda found: names[found.group(0)], text)

        started = time.monotonic()
        result = run(*(named(word) for word in words), timeout=120)
    assert result.returncode == 2, result
    assert "Traceback" not in result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"viewer-bridge {words[0]}: "), result.stderr
    assert named(said) in lines[0]
    assert not result.stdout
    assert time.monotonic() - started < 25  # refused at once, not after --duration 30
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "x.jpg").exists()


def test_ros_args_end_at_a_double_dash(tmp_path: Path) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 60)
    stats = tmp_path / "stats.json"
    result = run(
        "run", "--set", "foxglove.port=0", "--lcm-url", f"file://{log}?speed=0", "--stats-json", str(stats),
        "--ros-args", "-r", "__ns:=/sim1", "--", "--duration", "20",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    poses = json.loads(stats.read_text())["routes"]["poses"]
    assert poses["messages_in"] == 60 and poses["messages_out"] >= 1  # the whole log, replayed


def test_ros_settings_for_a_config_with_no_ros_route_are_reported(tmp_path: Path) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 10)
    result = run(
        "run", "-c", "builtin:foxglove", "--lcm-url", f"file://{log}?speed=0", "--set", "foxglove.port=0",
        "--set", "ros.namespace=/sim1", "--ros-args", "-r", "__ns:=/sim1", "--", "--duration", "30",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    for option in ("--set ros.namespace=/sim1", "--ros-args"):
        assert (
            f"viewer-bridge run: warning: {option} does nothing: no route of builtin:foxglove uses the ros "
            "transport (its routes use: lcm, foxglove)"
        ) in result.stderr.splitlines()


# --- the smaller things ---------------------------------------------------------------------------------


def test_version_and_defaults_in_every_help() -> None:
    version = run("--version")
    assert version.returncode == 0 and re.fullmatch(r"viewer-bridge \S+\n", version.stdout), version
    serve = " ".join(run("serve-render", "--help").stdout.split())  # as read, whatever the width wrapped
    assert "(default: 8000)" in serve and "(default: 268435456)" in serve and "(default: 4096x4096)" in serve
    shot = run("snapshot", "--help").stdout
    assert "(default: 640x480)" in shot and "(default: 45.0)" in shot
    assert "(default: None)" not in shot  # options with no default say nothing
    words = " ".join(shot.split())  # as read, whatever the terminal's width wrapped
    assert words.count("default: unsuffixed") == 1 and "(default: )" not in words  # each default once
    interfaces = run("ros-interfaces", "--help").stdout
    assert "[NAME ...]" in interfaces and "optional: the packages to install or show" in interfaces


def test_no_arguments_prints_the_help() -> None:
    result = run()
    assert result.returncode == 2 and not result.stderr, result
    assert (
        result.stdout.startswith("usage: viewer-bridge")
        and "{dump,demo,example,mappings,run" in result.stdout
    )


def test_one_route_is_one_route(tmp_path: Path) -> None:
    config = tmp_path / "one.yaml"
    config.write_text(
        f"lcm: {{url: '{lcm_url()}'}}\nroutes:\n  - name: relay\n    source: {{transport: lcm, name: A}}\n"
        "    translator: lcm_relay\n    destination: {transport: lcm, name: B}\n"
    )
    result = run("run", "-c", str(config), "--duration", "1")
    assert result.returncode == 0 and "viewer-bridge: 1 route running (" in result.stderr, result.stderr


def test_ros_interfaces_status_shows_the_names_asked_for() -> None:
    status = run("ros-interfaces", "status", "tf2_msgs")
    assert status.returncode == 0 and status.stdout.startswith("tf2_msgs: "), status
    unknown = run("ros-interfaces", "status", "no_such_msgs")
    assert unknown.returncode == 2
    assert (
        unknown.stderr
        == "viewer-bridge ros-interfaces: unknown interface package no_such_msgs (known: tf2_msgs)\n"
    )


def test_demo_says_when_it_starts() -> None:
    url = lcm_url(3)
    result = run("demo", "--url", url, "--duration", "0.5", "--rate", "20")
    assert result.returncode == 0, result.stderr
    first, last = result.stdout.splitlines()
    assert first == f"publishing the demo scene on {url} at 20 Hz, for 0.5 s"
    assert re.fullmatch(rf"published \d+ draw messages on {re.escape(url)}", last)


def test_snapshot_writes_the_format_its_name_asks_for(tmp_path: Path) -> None:
    from PIL import Image

    log = demo_log(tmp_path / "demo.lcmlog", 3)
    for name, kind in (("x.jpg", "JPEG"), ("x.jpeg", "JPEG"), ("x.png", "PNG")):
        result = run("snapshot", str(log), str(tmp_path / name), "--size", "64x48")
        assert result.returncode == 0, result.stderr
        with Image.open(tmp_path / name) as image:
            assert (image.format, image.size) == (kind, (64, 48))


def test_a_replayed_log_says_it_ended_and_the_stats_come_once_at_shutdown(tmp_path: Path) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 5)
    replay = run(
        "run", "-c", "builtin:foxglove", "--set", "foxglove.port=0", "--lcm-url", f"file://{log}?speed=0"
    )
    assert replay.returncode == 0, replay.stderr
    assert f"viewer-bridge: LCM file://{log} has ended: stopping" in replay.stderr
    # A duration that is a whole number of stats periods: one report at 2 s, the last one at 4 s
    # (before, the report due at 4 s came too, just before the same one at shutdown).
    live = run("run", "-c", "builtin:foxglove", "--set", "foxglove.port=0", "--lcm-url", lcm_url(4),
               "--demo", "--duration", "4", "--stats-period", "2")  # fmt: skip
    assert live.returncode == 0, live.stderr
    # Every route of builtin:foxglove is lazy and has no client: each report is one line of those
    # the demo feeds, with their in-rates, and no row.
    waiting = [line for line in live.stderr.splitlines() if " waiting for a subscriber: " in line]
    assert len(waiting) == 2 and " poses in " not in live.stderr, live.stderr
    assert re.search(r"foxglove_scene in \d+\.\d/s \(idle_skipped \d+\)", waiting[-1]), waiting


def test_demo_records_a_log_through_lcms_file_url(tmp_path: Path) -> None:
    """`demo --url 'file://LOG?mode=w'`: LCM's own file provider writes what the demo publishes."""
    log = tmp_path / "demo.lcmlog"
    result = run("demo", "--url", f"file://{log}?mode=w", "--duration", "1")
    assert result.returncode == 0, result.stderr
    channels = [event.channel for event in read_log(log)]
    assert channels[0] == "DRAKE_VIEWER_LOAD_ROBOT" and channels.count("DRAKE_VIEWER_DRAW") > 10
    replayed = run("run", "--lcm-url", str(log), "--set", "foxglove.port=0", "--stats-period", "60")
    assert replayed.returncode == 0 and "has ended: stopping" in replayed.stderr, replayed.stderr


def test_a_listening_zenoh_session_says_where_it_listens() -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    result = run("run", "-c", "builtin:zenoh", "--set", "zenoh.mode=router", "--set", f"zenoh.listen=[tcp/127.0.0.1:{port}]",
                 "--lcm-url", lcm_url(), "--duration", "1")  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert f"Zenoh router, listening on tcp/127.0.0.1:{port}" in result.stderr, result.stderr


@pytest.mark.parametrize(("config", "warned"), [("builtin:ign", False), ("builtin:gz", True)])
def test_ign_partition_is_fortress_own_name_and_a_warning_only_for_harmonic(
    config: str, warned: bool
) -> None:
    """The Gazebo guide tells Fortress users to set IGN_PARTITION: `builtin:ign` reads it quietly,
    `builtin:gz` (whose gz tools ignore it) says to set GZ_PARTITION."""
    environ = {key: value for key, value in os.environ.items() if not key.startswith(("GZ_", "IGN_"))}
    environ |= {"IGN_PARTITION": "docs_check", "IGN_IP": "127.0.0.1"}
    done = subprocess.run([*CLI, "run", "-c", config, "--lcm-url", lcm_url(), "--duration", "1"], capture_output=True,
                          text=True, timeout=120, env=environ)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert ("IGN_PARTITION is Fortress's name" in done.stderr) == warned, done.stderr


# --- --lcm-types: a lab's own types -----------------------------------------------------------------------


def test_a_bad_lcm_type_source_is_one_line_naming_it_and_exit_2(tmp_path: Path) -> None:
    broken = tmp_path / "types" / "broken.lcm"
    broken.parent.mkdir()
    broken.write_text("package lab;\n\nstruct broken_t {\n  int32_t a\n}\n")  # no ';' after a
    log = tmp_path / "empty.lcmlog"
    write_log(log, [LcmEvent("X", b"12345678", 0)])
    for command in (
        ("run", "--duration", "1", "--lcm-url", "memq://", "--lcm-types", str(broken.parent)),
        ("convert", str(log), str(tmp_path / "out.mcap"), "--lcm-types", str(broken)),
        ("dump", str(log), "--lcm-types", str(broken)),
        ("dump", str(log), "--lcm-types", "no_such_lcm_module_anywhere"),
    ):
        result = run(*command)
        assert result.returncode == 2, (command, result)
        lines = [line for line in result.stderr.splitlines() if "viewer-bridge" in line]
        assert len(lines) == 1 and "Traceback" not in result.stderr, (command, result.stderr)
        where = (
            f"{broken}:" if command[-1] != "no_such_lcm_module_anywhere" else "no_such_lcm_module_anywhere"
        )
        assert where in lines[0], (command, lines)
    assert not (tmp_path / "out.mcap").exists()


def test_dump_lcm_types_decodes_a_labs_own_type(
    tmp_path: Path,
    lcmgen_corpus: dict[str, type],  # noqa: F811 (the fixture, imported)
) -> None:
    import drake as drake_lcmtypes

    status = drake_lcmtypes.lcmt_iiwa_status()
    status.num_joints = 2
    for field in status.__slots__[2:]:
        setattr(status, field, [0.5, -0.25])
    log = tmp_path / "lab.lcmlog"
    write_log(log, [LcmEvent("IIWA_STATUS", status.encode(), 1),
                    LcmEvent("ARM_STATUS", arm_status(lcmgen_corpus).encode(), 2)])  # fmt: skip
    result = run("dump", str(log), "--json", "--lcm-types", str(CORPUS))
    assert result.returncode == 0, result.stderr
    drake, lab = [json.loads(line) for line in result.stdout.splitlines()]
    assert drake["type"] == "drake.lcmt_iiwa_status"  # Drake's types with no flag, beside the corpus
    assert drake["message"]["joint_position_measured"] == [0.5, -0.25]
    assert lab["type"] == "vbtest_lab.arm_status_t"
    assert lab["message"]["joint_names"] == ["shoulder", "elbow", "wrist ü"]  # ROS 2's field names
    assert lab["message"]["tool_tip"] == {"x": 0.5, "y": 0.25, "z": -0.125}
