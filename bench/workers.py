"""Benchmark: `viewer-bridge run --workers 2` against the same run with one worker (issue 42).

Run: .venv/bin/python bench/workers.py [--seconds 10] [--rounds 2] [--only draws|bus]

Two loads, each through the bridge as a process (`run -c FILE --workers N`), with its CPU time
taken from /proc as the sum over the bridge and every process under it (its workers, and the
resource tracker `spawn` starts), over the publishing window:

1. Draws: a 1000-link scene, then 1000-link `lcmt_viewer_draw`s at 2 kHz, through the default
   config's three per-draw routes (`tf`, world-frame `markers`, `poses`; policy `latest`, as they
   ship; `ros.shared_memory_mb: 32`, as docs/ros2.md advises for 248 kB MarkerArrays at 2 kHz) to
   raw rclpy subscribers, in a process of their own (`common.DdsCounter`), that count
   what arrives on each topic. Set-ups, interleaved: one worker pinned to CPU 0 with this process
   (the publisher) and the subscribers' on CPU 1, as
   bench/router.py runs it; one worker unpinned; two workers as `place` puts them (the routes are
   grouped by source pattern: `tf` and `markers` share the scene pattern and go to worker 0,
   `poses`, whose pattern is its own, to worker 1); two workers pinned with `worker: K`
   (`markers` alone on 0, `tf` and `poses` on 1), and the same with `policy: all` (every draw
   kept, up to 1000 waiting, where `latest` gives up the older of two). Then the goal's first half:
   the poses and TF routes alone (no markers), with one worker and with two placed by source (TF
   on 0, poses on 1). Nothing is pinned in the unpinned and two-worker
   set-ups: two workers need both cores, which the publisher and the subscribers share with them.
   Reported per route: delivered (messages the subscriber got, of draws sent), and the bridge's
   CPU per draw sent.
2. Small messages: 40 channels of `lcmt_iiwa_status` at 1500 Hz each (60,000 messages a second,
   from two publisher processes of 20 channels each) through the built-in zenoh config's
   `lcm_bus` route (`lcm_to_ros`) onto a Zenoh router in this process, and one Zenoh subscriber
   here counting every sample. As it ships, `lcm_bus` is one route (one source: one group) with a
   Zenoh destination, which `place` keeps on worker 0 unless pinned (Zenoh is no
   `several_processes` transport): the second worker would have nothing to do. So the route is
   split in two by channel (channels 00-19 and 20-39), each half pinned to a worker with
   `worker: K`; the baseline is the same split config with one worker. Each worker's LCM socket
   still reads every message on the bus (LCM matches channels in the process). Nothing is
   pinned: publishers, Zenoh router, subscriber and bridge share the two cores. Reported:
   delivered (samples the subscriber got, of messages sent), the same a second (the publishers
   reach fewer than 60,000 a second when the cores are short) and the bridge's CPU per message
   sent.

Before each counted window, a warm-up publishes until every route's topic (every channel's key)
has had a message, and then until what it left queued has drained; the bridge's and this
process's CPU shares are over the window and its drain.

Each set-up runs `--rounds` times, interleaved, and keeps its better round whole (disturbances on
a shared machine only lose messages): the one whose least delivered route delivered most (draws),
or that delivered most messages a second.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import lcm
import yaml
from common import (
    DdsCounter,
    Measure,
    Size,
    flat_stats,
    iiwa_status_bytes,
    machine_busy_seconds,
    paced,
    settle,
    tree_cpu_seconds,
)
from router import DEFAULT_ALL, DEFAULT_LATEST, DISCOVERY_S, URL, frame, scene
from zenoh_routes import _free_port, zenoh_session

from viewer_bridge.config.bridge import BUILTIN_CONFIGS, DEFAULT_CONFIG, load_config
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.router.workers import place
from viewer_bridge.transports.lcm import LcmBus

DRAW_HZ = 2000.0
LINKS = 1000
DRAW_TOPICS = {  # route -> (topic, type) its subscriber counts on
    "poses": ("/drake/poses", "geometry_msgs/msg/PoseArray"),
    "tf": ("/tf", "tf2_msgs/msg/TFMessage"),
    "markers": ("/drake/markers", "visualization_msgs/msg/MarkerArray"),
}
SPLIT_DRAWS = {"markers": 0, "tf": 1, "poses": 1}  # worker: K of the pinned two-worker set-up
# The draws' 248 kB MarkerArrays at 2 kHz need a larger Fast DDS shared-memory segment than its own
# (docs/ros2.md, bench/dds_segment.py); every draws set-up has it.
LARGE_MESSAGES = "ros: {shared_memory_mb: 32}\n"

BUS_CHANNELS = tuple(f"WORKERS_IIWA_{index:02d}" for index in range(40))
BUS_HZ = 1500.0  # per channel
BUS_PUBLISHERS = 2  # processes, each with its share of the channels
BUS_HALVES = ("WORKERS_IIWA_[01][0-9]", "WORKERS_IIWA_[23][0-9]")  # the split lcm_bus routes' channels


class Bridge:
    """`viewer-bridge run -c FILE --workers N` as a process, on `cores` (None: any)."""

    def __init__(self, config: str, workers: int | str, folder: Path, cores: set[int] | None) -> None:
        path = folder / "workers.yaml"
        path.write_text(config)
        self.stats = folder / "stats.json"
        self.stats.unlink(missing_ok=True)
        command = [sys.executable, "-m", "viewer_bridge.cli.main", "run", "-c", str(path), "--lcm-url", URL,
                   "--workers", str(workers), "--stats-json", str(self.stats), "--stats-period", "1"]  # fmt: skip
        preexec = (lambda: os.sched_setaffinity(0, cores)) if cores is not None else None
        self.process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, preexec_fn=preexec)
        assert self.process.stderr is not None
        self.placement: list[str] = []  # the parent's line per worker: its pid and its routes
        ready = " running"  # "N routes running (...)" in one process, "N workers running" with workers
        for line in self.process.stderr:
            if ": worker " in line and " (pid " in line:
                self.placement.append(line.split("viewer-bridge: ", 1)[-1].strip())
            if ready in line and "worker " not in line.split("viewer-bridge:", 1)[0]:
                break
        else:
            raise RuntimeError(f"the bridge ended before it ran (exit code {self.process.wait()})")
        threading.Thread(target=self.process.stderr.read, daemon=True).start()

    def cpu_seconds(self) -> float:
        return tree_cpu_seconds(self.process.pid)

    def stop(self) -> dict[str, Any]:
        """Stop it (SIGINT, as Ctrl-C), and its last stats: written as it closes."""
        self.process.send_signal(2)
        self.process.wait(timeout=30)
        return flat_stats(json.loads(self.stats.read_text()))


def without(config: str, *names: str) -> str:
    """`config` without the routes `names`."""
    document = yaml.safe_load(config)
    document["routes"] = [route for route in document["routes"] if route["name"] not in names]
    return yaml.safe_dump(document, sort_keys=False)


def routes_of(config: str) -> list[str]:
    """The routes of `config` that `DRAW_TOPICS` counts, in its order."""
    named = {route["name"] for route in yaml.safe_load(config)["routes"]}
    return [route for route in DRAW_TOPICS if route in named]


def with_workers(config: str, pins: dict[str, int]) -> str:
    """`config` with `worker: K` on the routes named in `pins`."""
    document = yaml.safe_load(config)
    for route in document["routes"]:
        if route["name"] in pins:
            route["worker"] = pins[route["name"]]
    return yaml.safe_dump(document, sort_keys=False)


def placement(config: str, workers: int) -> str:
    """Where `place` puts `config`'s routes: "worker 0: a, b; worker 1: c"."""
    with tempfile.NamedTemporaryFile("w", suffix=".yaml") as file:
        file.write(config)
        file.flush()
        placed = place(load_config(file.name), workers)
    return "; ".join(f"worker {index}: {', '.join(route.name for route in routes) or 'nothing'}"
                     for index, routes in enumerate(placed))  # fmt: skip


# 1. Draws ------------------------------------------------------------------------------------


def quiet(arrived: Any, at_most: float) -> None:
    """Until `arrived()` (a count of arrivals) has not moved for 0.3 s, at most `at_most` seconds:
    what the warm-up left queued has drained before the counted window starts."""
    last, still = arrived(), time.monotonic()
    deadline = still + at_most
    while (now := time.monotonic()) < deadline and now - still < 0.3:
        time.sleep(0.05)
        if (count := arrived()) != last:
            last, still = count, time.monotonic()


def draws(names: tuple[str, ...], how_many: int = 64) -> list[bytes]:
    """`how_many` encoded draws, sent in turn (encoding each anew would cost the publisher 1/4 of a core)."""
    encoder = DrawEncoder()
    return [encoder.encode(frame(names, sequence)) for sequence in range(1, how_many + 1)]


def draw_run(
    label: str,
    config: str,
    workers: int | str,
    pinned: bool,
    folder: Path,
    seconds: float,
    large: bool = True,
    counted: list[str] | None = None,
) -> dict[str, float]:
    """One bridge, 1000-link draws at 2 kHz: delivered per route, and CPU per draw; `large`: with
    `ros.shared_memory_mb: 32` (`LARGE_MESSAGES`); `counted`: the routes subscribed to (default:
    those of `DRAW_TOPICS` in the config)."""
    the_scene = scene(LINKS)
    encoded = draws(tuple(link.name for link in the_scene.links))
    everywhere = os.sched_getaffinity(0)
    if pinned:
        os.sched_setaffinity(0, {1})  # the publisher and the subscribers; the bridge gets CPU 0
    try:
        bridge = Bridge((LARGE_MESSAGES if large else "") + config, workers, folder, {0} if pinned else None)
        routes = counted or routes_of(config)
        counter = DdsCounter({route: DRAW_TOPICS[route] for route in routes})
        bus = LcmBus(URL)
        settle(counter.sees_bridge, DISCOVERY_S)
        bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(the_scene).encode())
        # Warm-up (DDS matching, first allocations), until every route's topic has had a message:
        # the subscriber may have seen one worker's node before the other's.
        deadline = time.monotonic() + DISCOVERY_S
        while True:
            paced(
                lambda i: bus.publish("DRAKE_VIEWER_DRAW", encoded[i % len(encoded)]),
                0,
                DRAW_HZ,
                min(1.0, seconds),
            )
            if len(counter.seen) == len(routes) or time.monotonic() > deadline:
                break
        quiet(lambda: counter.total, 3.0)
        counter.counting.set()
        cpu_before, started = bridge.cpu_seconds(), time.monotonic()
        here_before = tree_cpu_seconds(os.getpid()) - cpu_before  # the publisher and the subscriber process
        machine_before = machine_busy_seconds()
        sent = paced(
            lambda i: bus.publish("DRAKE_VIEWER_DRAW", encoded[i % len(encoded)]), 0, DRAW_HZ, seconds
        )
        settle(lambda: min(counter.counts.values()) >= sent, min(1.0, seconds))  # what was queued drains
        cpu_after = bridge.cpu_seconds()
        cpu, here = cpu_after - cpu_before, tree_cpu_seconds(os.getpid()) - cpu_after - here_before
        machine = machine_busy_seconds() - machine_before
        elapsed = time.monotonic() - started
        counter.counting.clear()
        stats = bridge.stop()
        counter.close()
        bus.close()
    finally:
        os.sched_setaffinity(0, everywhere)
    result: dict[str, float] = {"sent": sent, "cpu_us_per_draw": cpu / max(sent, 1) * 1e6, "cores": cpu / elapsed,
                                "cores_here": here / elapsed, "machine_cores": machine / elapsed}  # fmt: skip
    for route, count in counter.counts.items():
        result[route] = 100.0 * count / max(sent, 1)
        result[f"{route}_published"] = stats.get(route, {}).get("messages_out", 0)
        # Of the route's last 4096 messages, as its stats keep them.
        result[f"{route}_p99_ms"] = stats.get(route, {}).get("latency_ms", {}).get("p99", float("nan"))
    result["score"] = min(result[route] for route in routes)
    print(f"   {label:<36} sent {sent:6d}, delivered " + ", ".join(f"{route} {result[route]:5.1f}%" for route in routes)
          + f"; bridge CPU {result['cpu_us_per_draw']:4.0f} us/draw ({result['cores']:.2f} cores; publisher and "
          f"subscribers {result['cores_here']:.2f}; the machine {result['machine_cores']:.2f})"
          + (f"  [{' | '.join(bridge.placement)}]" if bridge.placement else ""), flush=True)  # fmt: skip
    return result


POSES_AND_TF = without(DEFAULT_LATEST, "markers")
DRAW_SETUPS = {  # label -> (config, workers, pinned to CPU 0)
    # The goal's first half: the poses and TF routes alone (the markers route left out).
    "poses + tf, 1 worker": (POSES_AND_TF, 1, False),
    "poses + tf, 2 workers, placed by source": (POSES_AND_TF, 2, False),
    "1 worker, pinned to CPU 0": (DEFAULT_LATEST, 1, True),
    "1 worker, unpinned": (DEFAULT_LATEST, 1, False),
    "2 workers, placed by source": (DEFAULT_LATEST, 2, False),
    "2 workers, pinned by worker: K": (with_workers(DEFAULT_LATEST, SPLIT_DRAWS), 2, False),
    # The same with `policy: all` (every draw kept, up to 1000 waiting): whether two workers carry
    # every draw when a late one may wait, where `latest` gives up the older of two at each stall.
    "2 workers, pinned by worker: K, policy all": (with_workers(DEFAULT_ALL, SPLIT_DRAWS), 2, False),
}


# The held-out soak's shape: the built-in default config as it ships (every route, lazy ones idle, no
# larger DDS segment), an rclpy subscriber on poses and TF only, `--workers` 1, 2 and auto.
SOAK_CONFIG = DEFAULT_CONFIG.replace("port: 8765", "port: 0")  # any free port: the machine is shared
SOAK_ROUTES = ["poses", "tf"]
SOAK_SETUPS = {"default config, --workers 1": "1", "default config, --workers 2": "2",
               "default config, --workers auto": "auto"}  # fmt: skip


def soak_run(label: str, workers: str, folder: Path, seconds: float) -> dict[str, float]:
    return draw_run(label, SOAK_CONFIG, workers, False, folder, seconds, large=False, counted=SOAK_ROUTES)


# 2. Small messages ---------------------------------------------------------------------------


def bus_config(endpoint: str, split: bool) -> str:
    """The built-in zenoh config's `lcm_bus` route alone; `split`: two copies of it, one per half
    of the channels, pinned to workers 0 and 1."""
    [shipped] = [r for r in yaml.safe_load(BUILTIN_CONFIGS["zenoh"])["routes"] if r["name"] == "lcm_bus"]
    routes = [shipped]
    if split:
        routes = [{**shipped, "name": f"lcm_bus_{index}", "worker": index,
                   "source": {**shipped["source"], "name": f"({half})"}}
                  for index, half in enumerate(BUS_HALVES)]  # fmt: skip
    return yaml.safe_dump({"zenoh": {"connect": [endpoint]}, "routes": routes}, sort_keys=False)


def publisher_child(url: str, channels: list[str], rate_hz: float) -> None:
    """A publisher process: each line on stdin is a number of seconds to publish `channels` at
    `rate_hz` each, round-robin; it answers with how many it sent."""
    bus = lcm.LCM(url)
    data = iiwa_status_bytes()
    for line in sys.stdin:
        sent = paced(lambda i: bus.publish(channels[i % len(channels)], data), 0, rate_hz * len(channels),
                     float(line))  # fmt: skip
        print(sent, flush=True)


class Publishers:
    """`BUS_PUBLISHERS` publisher processes sharing `BUS_CHANNELS`, publishing together."""

    def __init__(self) -> None:
        shares = [BUS_CHANNELS[index::BUS_PUBLISHERS] for index in range(BUS_PUBLISHERS)]
        self.processes = [
            subprocess.Popen([sys.executable, __file__, "--publish", URL, ",".join(share), str(BUS_HZ)],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
            for share in shares
        ]  # fmt: skip

    def publish(self, seconds: float) -> int:
        for process in self.processes:
            assert process.stdin is not None
            process.stdin.write(f"{seconds}\n")
            process.stdin.flush()
        return sum(int(process.stdout.readline()) for process in self.processes if process.stdout is not None)

    def cpu_seconds(self) -> float:
        return sum(tree_cpu_seconds(process.pid) for process in self.processes)

    def close(self) -> None:
        for process in self.processes:
            assert process.stdin is not None
            process.stdin.close()
            process.wait(timeout=10)


class Samples:
    """One Zenoh subscriber on every key under `prefix`; counts samples while `counting` is set."""

    def __init__(self, endpoint: str, prefix: str) -> None:
        self.session = zenoh_session("client", {"connect": [endpoint]})
        self.counting = threading.Event()
        self.count = 0
        self.total = 0  # every sample, counting or not
        self.seen: set[str] = set()  # the keys that have had a sample (while not counting)
        self._held = self.session.declare_subscriber(f"{prefix}/**", self._arrived)

    def _arrived(self, sample: Any) -> None:
        self.total += 1
        if self.counting.is_set():
            self.count += 1
        else:
            self.seen.add(str(sample.key_expr))

    def close(self) -> None:
        del self._held
        self.session.close()  # type: ignore[no-untyped-call]


def bus_run(label: str, workers: int, folder: Path, seconds: float, endpoint: str) -> dict[str, float]:
    """One bridge, 60,000 small messages a second: delivered, and CPU per message."""
    domain = int(os.environ.get("ROS_DOMAIN_ID") or 0)
    bridge = Bridge(bus_config(endpoint, split=True), workers, folder, None)
    samples = Samples(endpoint, f"{domain}/lcm")
    publishers = Publishers()
    time.sleep(min(1.0, seconds))
    warm_up, deadline = 0, time.monotonic() + 10.0
    while len(samples.seen) < len(BUS_CHANNELS) and time.monotonic() < deadline:  # both halves' routes woke
        # the lazy routes wake, each channel's publisher appears
        warm_up += publishers.publish(min(1.0, seconds))
    quiet(lambda: samples.total, 3.0)
    samples.counting.set()
    cpu_before, others_before = bridge.cpu_seconds(), publishers.cpu_seconds() + time.process_time()
    started, machine_before = time.monotonic(), machine_busy_seconds()
    sent = publishers.publish(seconds)
    settle(lambda: samples.count >= sent, min(2.0, seconds))  # what was queued drains
    cpu, elapsed = bridge.cpu_seconds() - cpu_before, time.monotonic() - started
    machine = machine_busy_seconds() - machine_before
    others = publishers.cpu_seconds() + time.process_time() - others_before
    samples.counting.clear()
    stats = bridge.stop()
    publishers.close()
    samples.close()
    received = sum(r["messages_in"] for name, r in stats.items() if name != "transports")
    result = {
        "sent": float(sent),
        "delivered": 100.0 * samples.count / max(sent, 1),
        "per_second": samples.count / seconds,
        "cpu_us_per_message": cpu / max(sent, 1) * 1e6,
        "cores": cpu / elapsed,  # the window: publishing, then the drain
        "cores_here": others / elapsed,
        "machine_cores": machine / elapsed,
        # of the whole run's: the stats count from the start
        "taken_in": 100.0 * received / max(warm_up + sent, 1),
    }
    result["score"] = result["per_second"]
    print(f"   {label:<36} sent {sent:7d} ({sent / seconds:.0f}/s), delivered {result['delivered']:5.1f}% "
          f"({result['per_second']:.0f}/s), the "
          f"routes took in {result['taken_in']:.1f}% (whole run); bridge CPU {result['cpu_us_per_message']:5.1f} us/message "
          f"({result['cores']:.2f} cores; publishers, Zenoh router and subscriber {result['cores_here']:.2f}; "
          f"the machine {result['machine_cores']:.2f})"
          + (f"  [{' | '.join(bridge.placement)}]" if bridge.placement else ""),
          flush=True)  # fmt: skip
    return result


BUS_SETUPS = {"1 worker": 1, "2 workers, lcm_bus split and pinned": 2}


# Both ----------------------------------------------------------------------------------------


def load_average() -> str:
    """The machine's load over the last 1, 5 and 15 minutes, and its cores: how busy it was."""
    return f"{' '.join(Path('/proc/loadavg').read_text().split()[:3])} on {os.cpu_count()} cores"


def keep(best: dict[str, dict[str, float]], label: str, result: dict[str, float]) -> None:
    """`best[label]` is the better round, whole (its figures are not mixed with another round's): the
    one that delivered more (draws: the least delivered route; small messages: per second)."""
    if label not in best or result["score"] > best[label]["score"]:
        best[label] = result


def compare(
    seconds: float, rounds: int, parts: tuple[str, ...] = ("draws", "bus")
) -> dict[str, dict[str, float]]:
    """Every set-up of `parts`, `rounds` times interleaved; per figure, the better round."""
    best: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        if "draws" in parts:
            print(f"1. {LINKS}-link draws at {DRAW_HZ:g} Hz for {seconds:g} s, the default per-draw routes (latest); "
                  f"placed by source: {placement(DEFAULT_LATEST, 2)}")  # fmt: skip
            for _ in range(rounds):
                for label, (config, workers, pinned) in DRAW_SETUPS.items():
                    keep(best, label, draw_run(label, config, workers, pinned, folder, seconds))
        if "soak" in parts:
            print(f"0. the held-out soak's shape: {LINKS}-link draws at {DRAW_HZ:g} Hz for {seconds:g} s, the "
                  f"built-in default config, an rclpy subscriber on poses and tf; load {load_average()}")  # fmt: skip
            for _ in range(rounds):
                for label, workers in SOAK_SETUPS.items():
                    keep(best, label, soak_run(label, workers, folder, seconds))
        if "bus" in parts:
            endpoint = f"tcp/127.0.0.1:{_free_port()}"
            print(f"2. {len(BUS_CHANNELS)} channels of lcmt_iiwa_status at {BUS_HZ:g} Hz each for {seconds:g} s "
                  f"onto Zenoh; lcm_bus as shipped, 2 workers: {placement(bus_config(endpoint, False), 2)}; "
                  f"split: {placement(bus_config(endpoint, True), 2)}")  # fmt: skip
            router = zenoh_session("router", {"listen": [endpoint]})
            try:
                for _ in range(rounds):
                    for label, workers in BUS_SETUPS.items():
                        keep(best, label, bus_run(label, workers, folder, seconds, endpoint))
            finally:
                router.close()  # type: ignore[no-untyped-call]
    return best


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Issue 42: what a second worker buys, against one worker in the same run."""
    best = compare(size.pick(full=10.0, quick=4.0, smoke=0.5), size.pick(full=2, quick=1, smoke=1))
    rows = []
    draws_setup = (
        f"{LINKS}-link draws at {DRAW_HZ / 1000:g} kHz, default per-draw routes, ros.shared_memory_mb 32"
    )
    shared = "unpinned: publisher and subscribers share the 2 cores"
    one = best["1 worker, unpinned"]
    for label, how in (
        ("2 workers, placed by source", "placed by source"),
        ("2 workers, pinned by worker: K", "pinned"),
    ):
        two = best[label]
        how = f"{how} ({placement(DRAW_SETUPS[label][0], 2)})"
        for route in DRAW_TOPICS:
            rows.append(Measure(f"workers: {route} delivered of draws sent, {draws_setup}, --workers 2 {how}, {shared} "
                                "(baseline: --workers 1, unpinned)", two[route], one[route], "%",
                                "none (reported)", None))  # fmt: skip
        rows.append(Measure(f"workers: bridge CPU per draw sent (all its processes), {draws_setup}, --workers 2 {how}, "
                            f"{shared} (baseline: --workers 1, unpinned)", two["cpu_us_per_draw"],
                            one["cpu_us_per_draw"], "us", "none (reported)", None))  # fmt: skip
        rows.extend(
            whole_run(f"{draws_setup}, --workers 2 {how} (baseline: --workers 1, unpinned)", two, one)
        )
    alone, both = best["poses + tf, 1 worker"], best["poses + tf, 2 workers, placed by source"]
    for route in routes_of(POSES_AND_TF):
        rows.append(
            Measure(
                f"workers: {route} delivered of draws sent, {draws_setup} without markers (poses and TF), "
                f"--workers 2 placed by source ({placement(POSES_AND_TF, 2)}), {shared} (baseline: "
                "--workers 1, unpinned)",
                both[route],
                alone[route],
                "%",
                ">= 99.5",
                both[route] >= 99.5,
            )
        )
    latest, every = best["2 workers, pinned by worker: K"], best["2 workers, pinned by worker: K, policy all"]
    for route in DRAW_TOPICS:
        rows.append(
            Measure(
                f"workers: {route} delivered of draws sent, {draws_setup} with `policy: all` (every draw "
                f"kept, up to 1000 waiting), --workers 2 pinned, {shared} (baseline: the same with "
                "`latest`, as shipped)",
                every[route],
                latest[route],
                "%",
                "none (reported)",
                None,
            )
        )
        rows.append(Measure(f"workers: {route} latency LCM receive -> published, p99 of its last 4096 draws, same, "
                            "`policy: all` (baseline: `latest`)", every[f"{route}_p99_ms"], latest[f"{route}_p99_ms"], "ms",
                            "none (reported: what keeping every draw costs)", None))  # fmt: skip
    pinned = best["1 worker, pinned to CPU 0"]
    rows.append(Measure(f"workers: poses / tf / markers delivered, {draws_setup}, --workers 1 pinned to CPU 0 as "
                        "bench/router.py, publisher on CPU 1: the least of the three (baseline: --workers 1, unpinned)",
                        min(pinned[route] for route in DRAW_TOPICS), min(one[route] for route in DRAW_TOPICS), "%",
                        "none (reported)", None))  # fmt: skip
    bus_setup = (f"{len(BUS_CHANNELS)} channels of lcmt_iiwa_status at {BUS_HZ:g} Hz ({len(BUS_CHANNELS) * BUS_HZ:,.0f}/s) "
                 f"-> Zenoh, lcm_bus split in 2 routes by channel")  # fmt: skip
    shared = f"unpinned: {BUS_PUBLISHERS} publisher processes, Zenoh router and subscriber share the 2 cores"
    one, two = best["1 worker"], best["2 workers, lcm_bus split and pinned"]
    rows.append(Measure(f"workers: delivered of messages sent, {bus_setup}, --workers 2 (a half pinned to each), "
                        f"{shared} (baseline: --workers 1)", two["delivered"], one["delivered"], "%",
                        "none (reported)", None))  # fmt: skip
    rows.append(Measure("workers: messages delivered a second, same, --workers 2 (baseline: --workers 1)",
                        two["per_second"], one["per_second"], "/s", "none (reported; the publishers slow down too)",
                        None))  # fmt: skip
    rows.append(Measure("workers: bridge CPU per message sent (all its processes), same, --workers 2 "
                        "(baseline: --workers 1)", two["cpu_us_per_message"], one["cpu_us_per_message"], "us",
                        "none (reported)", None))  # fmt: skip
    rows.extend(whole_run("same, --workers 2 (baseline: --workers 1)", two, one))
    return rows


def whole_run(setup: str, two: dict[str, float], one: dict[str, float]) -> list[Measure]:
    """The CPU the whole run used, in cores: its processes (the bridge's, the publishers, the
    subscribers, the Zenoh router) and the machine as a whole (/proc/stat: the kernel's time moving
    packets too). Near the machine's 2, the cores, not the bridge, bound what a second worker adds."""
    cores = f"in cores of the machine's {os.cpu_count()}, {setup}"
    bound = "none: where it nears the cores, they bound it"
    return [
        Measure(f"workers: CPU the run's processes used (bridge + publishers + subscribers), {cores}",
                two["cores"] + two["cores_here"], one["cores"] + one["cores_here"], "cores", bound, None),
        Measure(f"workers: CPU the machine used meanwhile (every process and the kernel, /proc/stat), {cores}",
                two["machine_cores"], one["machine_cores"], "cores", bound, None),
    ]  # fmt: skip


# 3. A model past this machine ------------------------------------------------------------------
#
# CPU per message of the bus load, per worker, as the worker count N grows, for three designs:
#   every worker reads every datagram (today): a worker pays `receive` for every message on the bus
#     and `work` for its 1/N share:        receive + work / N          (the bus: N * receive + work)
#   one receiver hands channels to workers over pipes: the receiver pays receive + send for every
#     message, a worker (take + work) for its share: the receiver's receive + send caps the rate
#   channels split across multicast groups (or filtered by channel in the kernel) by worker: a
#     worker reads only its share:         (receive + work) / N
# `receive` and `work` are fitted to the two measured points (the bridge's CPU per message taken in
# with --workers 1 and 2: c1 = receive + work, c2 = 2 receive + work); send and take are a pipe's,
# measured.

MODEL_WORKERS = (1, 2, 3, 4, 6, 8, 12, 16)
DESIGNS = ("every worker reads all", "one receiver, pipes", "multicast group per worker")


def fit(one: float, two: float) -> tuple[float, float]:
    """(receive, work) in us per message from the bridge's CPU per message with 1 and 2 workers."""
    receive = max(0.0, two - one)
    return receive, max(0.0, one - receive)


def _take(connection: Any, count: int, answer: Any) -> None:
    started = time.process_time()
    for _ in range(count):
        connection.recv_bytes()
    answer.send(time.process_time() - started)


def pipe_costs(size: int = 700, count: int = 20000) -> tuple[float, float]:
    """(send, take) CPU us per message of `size` bytes through a pipe to another process."""
    import multiprocessing

    spawn = multiprocessing.get_context("spawn")
    take, give = spawn.Pipe(duplex=False)
    answer_in, answer_out = spawn.Pipe(duplex=False)
    child = spawn.Process(target=_take, args=(take, count, answer_out))
    child.start()
    data = b"x" * size
    started = time.process_time()
    for _ in range(count):
        give.send_bytes(data)
    sent = time.process_time() - started
    taken = answer_in.recv()
    child.join()
    return sent / count * 1e6, taken / count * 1e6


def model(
    receive: float, work: float, send: float, take: float, workers: int
) -> dict[str, tuple[float, float]]:
    """Per design: (the most messages a second it carries when each process has a core of its own,
    the CPU us a message costs its processes together)."""
    every = receive + work / workers
    receiver, share = receive + send, (take + work) / workers  # the receiver is a process more
    split = (receive + work) / workers
    return {
        DESIGNS[0]: (1e6 / every, workers * receive + work),
        DESIGNS[1]: (1e6 / max(receiver, share), receive + send + take + work),
        DESIGNS[2]: (1e6 / split, receive + work),
    }


def model_table(one: float, two: float, send: float, take: float) -> str:
    receive, work = fit(one, two)
    lines = [f"measured: --workers 1 {one:.1f} us/message, --workers 2 {two:.1f} (both processes); fitted: "
             f"receive {receive:.1f} us, work {work:.1f} us a message; a pipe: send {send:.1f}, take {take:.1f} us",
             "| workers | " + " | ".join(f"{d}: most msgs/s | CPU us/msg, all processes" for d in DESIGNS) + " |",
             "|---:|" + "---:|---:|" * len(DESIGNS)]  # fmt: skip
    for workers in MODEL_WORKERS:
        row = model(receive, work, send, take, workers)
        cells = " | ".join(f"{row[d][0]:,.0f} | {row[d][1]:.1f}" for d in DESIGNS)
        measured = {
            1: f" (measured: {1e6 / one:,.0f}, {one:.1f})",
            2: f" (measured: {2e6 / two:,.0f}, {two:.1f})",
        }
        lines.append(f"| {workers}{measured.get(workers, '')} | {cells} |")
    return "\n".join(lines)


def model_figure(path: Path, one: float, two: float, send: float, take: float) -> None:
    """The model's most messages a second against workers, one line per design, as a PNG."""
    from PIL import Image, ImageDraw, ImageFont

    receive, work = fit(one, two)
    width, height, margin = 900, 520, 80
    image = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(image)
    font = ImageFont.truetype("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", 15)
    rates = {d: [model(receive, work, send, take, n)[d][0] for n in range(1, 17)] for d in DESIGNS}
    top = max(max(values) for values in rates.values()) * 1.05

    def at(workers: int, rate: float) -> tuple[float, float]:
        return (margin + (workers - 1) / 15 * (width - 2 * margin),
                height - margin - rate / top * (height - 2 * margin))  # fmt: skip

    draw.line([at(1, 0), at(16, 0)], fill="black")
    draw.line([at(1, 0), at(1, top)], fill="black")
    for workers in (1, 2, 4, 8, 12, 16):
        x, y = at(workers, 0)
        draw.text((x - 5, y + 8), str(workers), fill="black", font=font)
    for step in range(0, 6):
        rate = top * step / 5
        x, y = at(1, rate)
        draw.text((x - 72, y - 8), f"{rate / 1000:,.0f}k", fill="black", font=font)
    draw.text((width / 2 - 60, height - 35), "worker processes", fill="black", font=font)
    draw.text((margin, 15), f"most messages a second, each process on a core (fit: receive {receive:.1f} us, "
              f"work {work:.1f} us, pipe {send:.1f} + {take:.1f} us)", fill="black", font=font)  # fmt: skip
    for index, (design, color) in enumerate(
        zip(DESIGNS, ("firebrick", "darkorange", "seagreen"), strict=True)
    ):
        draw.line([at(n, rate) for n, rate in enumerate(rates[design], start=1)], fill=color, width=3)
        draw.text((margin + 20, 45 + 20 * index), design, fill=color, font=font)
    for workers, busiest in ((1, one), (2, two / 2)):  # measured: a worker's share of the 2 is half the sum
        x, y = at(workers, 1e6 / busiest)
        draw.ellipse([x - 5, y - 5, x + 5, y + 5], outline="black", width=2)
    image.save(path)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument(
        "--only", choices=["soak", "draws", "bus", "model"], help="one of the loads, or the model"
    )
    parser.add_argument(
        "--fit",
        nargs=2,
        type=float,
        metavar=("C1", "C2"),
        help="the model from these us/message with 1 and 2 workers, without measuring them",
    )
    parser.add_argument("--figure", type=Path, help="with --only model: draw the model as this PNG")
    parser.add_argument("--publish", nargs=3, metavar=("URL", "CHANNELS", "HZ"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publish:
        url, channels, rate = args.publish
        publisher_child(url, channels.split(","), float(rate))
        return
    if args.only == "model":
        if args.fit:
            one, two = args.fit
        else:
            best = compare(args.seconds, args.rounds, ("bus",))
            # Per message the routes took in: a bridge short of a core leaves some to the kernel
            # (dropped unread), and CPU per message sent would count those as free.
            one, two = (
                100.0 * best[label]["cpu_us_per_message"] / best[label]["taken_in"] for label in BUS_SETUPS
            )
        send, take = pipe_costs()
        print(model_table(one, two, send, take))
        if args.figure:
            model_figure(args.figure, one, two, send, take)
        return
    best = compare(args.seconds, args.rounds, (args.only,) if args.only else ("soak", "draws", "bus"))
    print("\nbest of the rounds:")
    for label, figures in best.items():
        print(f"   {label:<36} " + ", ".join(f"{key} {value:.4g}" for key, value in figures.items()))


if __name__ == "__main__":
    main()
