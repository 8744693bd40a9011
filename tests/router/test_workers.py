"""`viewer-bridge run --workers N` end to end: the routes on worker processes, over a real LCM bus.

Two `lcm_relay` routes, A -> A_OUT and B -> B_OUT, are placed on two workers (one each: their
sources differ). What comes out must not depend on how many processes carry it; a worker killed
outright comes back while the other one's route keeps flowing; Ctrl-C stops them all.
"""

from __future__ import annotations

import json
import re
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

import lcm
import psutil
import pytest

from tests.conftest import lcm_url
from tests.peers import BridgeProcess, wait_for, write_config
from tests.test_router import LcmRecorder

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

CONFIG = "routes:\n" + "".join(
    f"""
  - name: relay_{channel.lower()}
    source: {{transport: lcm, name: {channel}}}
    translator: lcm_relay
    destination: {{transport: lcm, name: {channel}_OUT}}
    rate: {{policy: all}}
    qos: {{depth: 10000}}
"""
    for channel in ("A", "B")
)
COUNT = 300  # messages per input channel


@pytest.fixture
def recorder() -> Iterator[LcmRecorder]:
    bus = LcmRecorder(lcm_url(3))
    yield bus
    bus.close()


def start_bridge(folder: Path, workers: int, url: str) -> BridgeProcess:
    """The bridge on `workers` processes, returned once every route is subscribed."""
    config = write_config(folder, CONFIG)
    stats = str(folder / f"stats{workers}.json")
    bridge = BridgeProcess("-c", str(config), "--lcm-url", url, "--workers", str(workers),
                           "--stats-json", stats, "--stats-period", "1")  # fmt: skip
    bridge.wait_for_line("2 workers running" if workers > 1 else "2 routes running")
    return bridge


def worker_pid(bridge: BridgeProcess, index: int, after: int = 0) -> int:
    """The pid of worker `index`'s process, as the bridge logged it (the one after `after` starts)."""
    pattern = re.compile(rf"worker {index} \(pid (\d+)\): ")
    wait_for(lambda: len([line for line in bridge.lines if pattern.search(line)]) > after)
    started = [match for line in list(bridge.lines) if (match := pattern.search(line))]
    assert len(started) > after, "\n".join(bridge.lines)
    return int(started[after].group(1))


def gone(process: psutil.Process) -> bool:
    """Whether a process has ended (a zombie no parent has reaped yet has too)."""
    try:
        return process.status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


def test_two_workers_put_out_what_one_process_does(tmp_path: Path, recorder: LcmRecorder) -> None:
    sent = {channel: [f"{channel}{index}".encode() for index in range(COUNT)] for channel in ("A", "B")}
    outputs: dict[int, dict[str, list[bytes]]] = {}
    for workers in (1, 2):
        recorder.messages.clear()
        bridge = start_bridge(tmp_path, workers, recorder.url)
        try:
            bus = lcm.LCM(recorder.url)
            for index in range(COUNT):
                for channel in sent:
                    bus.publish(channel, sent[channel][index])
            assert wait_for(lambda: all(len(recorder.messages.get(f"{c}_OUT", [])) >= COUNT for c in sent))
            recorder.sync()
            outputs[workers] = {f"{c}_OUT": list(recorder.messages[f"{c}_OUT"]) for c in sent}
        finally:
            assert bridge.stop() == (130 if workers > 1 else 0), "\n".join(bridge.lines)
        if workers > 1:  # one route on each worker: their sources differ
            assert worker_pid(bridge, 0) != worker_pid(bridge, 1)
            assert any(re.search(r"worker 0 \(pid \d+\): relay_a$", line) for line in bridge.lines), (
                bridge.lines
            )
            assert any(re.search(r"worker 1 \(pid \d+\): relay_b$", line) for line in bridge.lines), (
                bridge.lines
            )
        stats = json.loads((tmp_path / f"stats{workers}.json").read_text())["routes"]  # merged: both routes
        assert {name: stats[name]["messages_out"] for name in ("relay_a", "relay_b")} == {
            "relay_a": COUNT, "relay_b": COUNT
        }  # fmt: skip
    assert outputs[1] == outputs[2] == {f"{c}_OUT": sent[c] for c in sent}


def test_a_killed_worker_is_restarted_and_the_other_flows_on(tmp_path: Path, recorder: LcmRecorder) -> None:
    bridge = start_bridge(tmp_path, 2, recorder.url)
    stop = threading.Event()

    def publish() -> None:  # numbered messages on both channels, 100 a second, until the end
        bus, index = lcm.LCM(recorder.url), 0
        while not stop.wait(0.01):
            bus.publish("A", b"%d" % index)
            bus.publish("B", b"%d" % index)
            index += 1

    publisher = threading.Thread(target=publish, daemon=True)
    publisher.start()
    try:
        assert wait_for(lambda: all(len(recorder.messages.get(c, [])) > 20 for c in ("A_OUT", "B_OUT")))
        first_a, other = worker_pid(bridge, 0), worker_pid(bridge, 1)
        a_before, b_before = len(recorder.messages["A_OUT"]), len(recorder.messages["B_OUT"])
        psutil.Process(first_a).send_signal(signal.SIGKILL)
        assert worker_pid(bridge, 0, after=1) != first_a  # a new process for worker 0
        bridge.wait_for_line("worker 0 died (signal 9): restarting it")
        a_after_kill = len(recorder.messages["A_OUT"])
        # relay_a flows again: messages published after the restart come out.
        assert wait_for(lambda: len(recorder.messages["A_OUT"]) > a_after_kill + 50), "\n".join(bridge.lines)
        b_by_then = list(recorder.messages["B_OUT"])
    finally:
        stop.set()
        publisher.join()
        code = bridge.stop()
    assert code == 130, "\n".join(bridge.lines)
    # relay_b never stopped: its worker is the same process, and every message numbered from before
    # the kill until relay_a flowed again came out, in order.
    assert worker_pid(bridge, 1) == other and not any("worker 1 died" in line for line in bridge.lines)
    numbers = [int(data) for data in b_by_then[b_before - 1 :]]
    assert len(numbers) > 50 and numbers == list(range(numbers[0], numbers[0] + len(numbers)))
    assert a_before > 20
    stats = json.loads((tmp_path / "stats2.json").read_text())
    assert stats["transports"]["workers"]["errors"] == {"restarted": 1}
    assert stats["routes"]["relay_b"]["messages_out"] >= len(b_by_then)


def test_ctrl_c_stops_every_worker_and_exits_130(tmp_path: Path, recorder: LcmRecorder) -> None:
    bridge = start_bridge(tmp_path, 2, recorder.url)
    family = psutil.Process(bridge.process.pid).children(recursive=True)
    workers = {worker_pid(bridge, 0), worker_pid(bridge, 1)}
    assert workers <= {process.pid for process in family}
    assert bridge.stop() == 130, "\n".join(bridge.lines)

    assert wait_for(lambda: all(gone(process) for process in family)), [p for p in family if not gone(p)]
    # The workers stopped as asked (closing their routes and sending their last stats), not killed.
    assert not any("did not stop" in line or "died" in line for line in bridge.lines), "\n".join(bridge.lines)


def test_ctrl_c_at_a_terminal_reaches_every_process_and_says_one_line(tmp_path: Path) -> None:
    """A terminal's Ctrl-C goes to the whole process group, workers included: the parent alone
    answers it, in one line, and nothing prints a traceback."""
    import os
    import subprocess
    import sys

    stats = tmp_path / "stats.json"
    command = [sys.executable, "-m", "viewer_bridge", "run", "--demo", "--workers", "2", "-q",
               "--set", "foxglove.port=0", "--stats-json", str(stats), "--stats-period", "1"]  # fmt: skip
    # A session of its own: its process group is the bridge and its workers, as at a terminal.
    bridge = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              start_new_session=True)  # fmt: skip
    try:
        assert wait_for(lambda: stats.exists() or bridge.poll() is not None, 120), bridge.communicate()
        family = psutil.Process(bridge.pid).children(recursive=True)
        os.killpg(bridge.pid, signal.SIGINT)
        _, stderr = bridge.communicate(timeout=60)
    finally:
        bridge.kill()
    assert bridge.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    assert stderr.splitlines()[-1] == "viewer-bridge run: interrupted: 2 workers stopped", stderr

    # every process of the group ends, if a moment after the parent under load
    assert wait_for(lambda: all(gone(process) for process in family), 60), [p for p in family if not gone(p)]


def test_workers_auto_says_what_it_counted_and_runs_that_many(tmp_path: Path, recorder: LcmRecorder) -> None:
    config = write_config(tmp_path, CONFIG)
    bridge = BridgeProcess("-c", str(config), "--lcm-url", recorder.url, "--workers", "auto")
    try:
        chosen = bridge.wait_for_line("--workers auto: ")
        match = re.search(r"--workers auto: (\d+) \((\d+) usable cores, [\d.]+ busy, 1 kept for the peers; "
                          r"the routes can use 2\)", chosen)  # fmt: skip
        assert match, chosen
        workers, cores = int(match.group(1)), int(match.group(2))
        assert 1 <= workers <= min(2, max(1, cores - 1))
        bridge.wait_for_line(f"{workers} workers running" if workers > 1 else "2 routes running")
    finally:
        code = bridge.stop()
    assert code == (130 if workers > 1 else 0), "\n".join(bridge.lines)
