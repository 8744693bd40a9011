"""Benchmark: the floor, what any Python process pays to move an LCM message onto Zenoh, beside
the bridge's routes doing the same.

Run: .venv/bin/python bench/floor.py [--seconds 10]

The floor is the least a Python process can do: `lcm.LCM.subscribe(".*")` and, in the callback,
`put` of the bytes on a Zenoh publisher per channel (key lcm/<channel>), nothing else. It runs as
a process of its own pinned to CPU 0, as the bridge does in bench/lcm_routes.py, under the same
traffic (20 channels of lcmt_iiwa_status at 500 Hz each, a Zenoh router and a subscriber on the
other core), and reads its CPU time per message from /proc/self/stat. The rows are the bridge's
CPU per message on its `relay` (the bytes as they are) and `lcm_bus` (lcm_to_ros: transcoded to
CDR) routes as multiples of the floor's, measured in the same run: what the router itself costs
over the bare minimum, and so what one core can carry before `--workers` must share the load.

At issue 42's rate (30,000 messages a second, bench/lcm_routes.py's delivery rows) the floor runs
again, onto Zenoh and onto ROS 2 over DDS (an rclpy publisher per channel, the LCM bytes published
as they are as serialised messages: about the size of their CDR, 412 bytes against 460), to the
same subscribers as the bridge's rows: what a bare Python process on the same core delivers there.
Those rows say how much of what the bridge's rows miss this machine's one core leaves to any
Python process.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import lcm
from common import DdsCounter, Measure, Size, settle
from lcm_routes import (
    CHANNELS,
    FAST_HZ,
    LCM_STAMP,
    RATE_HZ,
    Counting,
    Runner,
    compare,
    dds_counter,
    publish,
    run,
)
from router import URL
from zenoh_routes import zenoh_session

from viewer_bridge.transports.lcm import LcmBus


def cpu_seconds() -> float:
    """User + system CPU time of this process so far (/proc/self/stat fields 14 and 15)."""
    fields = Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def zenoh_publisher(endpoint: str) -> tuple[Callable[[str], Callable[[bytes], Any]], Callable[[], Any]]:
    """(a publish function per channel, on key lcm/<channel>; close)."""
    session = zenoh_session("client", {"connect": [endpoint]})
    return (lambda channel: session.declare_publisher(f"lcm/{channel}").put), session.close


def dds_publisher() -> tuple[Callable[[str], Callable[[bytes], Any]], Callable[[], Any]]:
    """(a publish function per channel, rclpy on /lcm/<channel> as the bridge's lcm_bus; close)."""
    import rclpy
    from rclpy.node import Node

    from viewer_bridge.transports.ros2 import message_class, qos_profile

    rclpy.init()
    node = Node("bench_floor")
    status = message_class("drake_lcm_msgs/msg/LcmtIiwaStatus")

    def close() -> None:
        node.destroy_node()  # type: ignore[no-untyped-call]
        rclpy.shutdown()

    return (lambda channel: node.create_publisher(status, f"/lcm/{channel}", qos_profile(100)).publish), close


# The floor's candidates: how the process waits for LCM (the main thread in `handle()`, the main
# thread in `handle_timeout(100)`, or a thread of its own in `handle_timeout(100)` while the main
# thread waits on stdin, as LcmBus does), and whether the subscription's queue is unbounded (as the
# bridge's: no silent drop past 30 queued) or LCM's default. The cheapest is the floor.
VARIANTS = ("handle", "handle_timeout", "thread", "handle_queue30")
MINIMAL = "minimal"  # bench/minimal_floor.py: the floor written from scratch, to check the others by


def serve(url: str, endpoint: str, target: str, variant: str = "thread") -> None:
    """The floor process: every LCM channel onto `target` (zenoh or dds), LCM waited for as
    `variant` says (`VARIANTS`); a line on stdin asks for its count and CPU."""
    os.sched_setaffinity(0, {0})
    publisher_for, close = dds_publisher() if target == "dds" else zenoh_publisher(endpoint)
    publishers: dict[str, Callable[[bytes], Any]] = {}
    received = [0]

    def forward(channel: str, data: bytes) -> None:
        put = publishers.get(channel)
        if put is None:
            put = publishers[channel] = publisher_for(channel)
        put(data)
        received[0] += 1

    bus = lcm.LCM(url)
    subscription = bus.subscribe(".*", forward)
    if variant != "handle_queue30":
        subscription.set_queue_capacity(0)  # as the bridge's: no silent drop at 30 queued
    stop = threading.Event()

    def answer() -> None:
        for _ in sys.stdin:
            print(json.dumps({"count": received[0], "cpu": cpu_seconds()}), flush=True)
        stop.set()
        if variant.startswith("handle_queue") or variant == "handle":
            os._exit(0)  # the main thread waits in handle() for a message that may never come

    def spin() -> None:
        while not stop.is_set():
            bus.handle_timeout(100)

    print("ready", flush=True)
    if variant == "thread":
        thread = threading.Thread(target=spin, daemon=True)
        thread.start()
        answer()
        thread.join()
        close()
        return
    threading.Thread(target=answer, daemon=True).start()  # blocked in read: costs the loop nothing
    if variant == "handle_timeout":
        spin()
    else:
        while True:
            bus.handle()


class Floor:
    """The floor process (`variant`, or bench/minimal_floor.py), started and asked from here."""

    def __init__(
        self, endpoint: str, target: str, variant: str = "thread", prefix: tuple[str, ...] = ()
    ) -> None:
        """`prefix`: what runs the process (valgrind, for bench/instructions.py)."""
        here = Path(__file__).parent
        if variant == MINIMAL:
            command = [*prefix, sys.executable, str(here / "minimal_floor.py"), URL, endpoint]
        else:
            command = [*prefix, sys.executable, __file__, "--serve", URL, endpoint, target, variant]
        self.process = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            preexec_fn=lambda: os.sched_setaffinity(0, {0}),
        )
        assert self.ask_line() == "ready"

    def ask_line(self) -> str:
        assert self.process.stdout is not None
        return self.process.stdout.readline().strip()

    def state(self) -> dict[str, float]:
        assert self.process.stdin is not None
        self.process.stdin.write("?\n")
        self.process.stdin.flush()
        return json.loads(self.ask_line())  # type: ignore[no-any-return]

    def stop(self) -> None:
        assert self.process.stdin is not None
        self.process.stdin.close()
        self.process.wait(timeout=20)


def run_floor(
    folder: Path,
    seconds: float,
    endpoint: str,
    rate_hz: float = RATE_HZ,
    target: str = "zenoh",
    variant: str = "thread",
) -> dict[str, float]:
    """The floor (`variant`, or `MINIMAL`) under the traffic bench/lcm_routes.py gives the bridge
    (`rate_hz` per channel, onto `target`: zenoh or dds); its figures as `run`'s, with the latency
    from publish to the subscriber at 10,000 messages a second onto Zenoh."""
    floor = Floor(endpoint, target, variant)
    stamped = target == "zenoh" and rate_hz <= RATE_HZ
    subscriber: Counting | DdsCounter = (
        dds_counter() if target == "dds" else Counting(endpoint, "lcm", LCM_STAMP if stamped else None)
    )
    bus = LcmBus(URL)
    time.sleep(1.0)
    publish(bus, 1.0, rate_hz)  # every channel's publisher appears
    time.sleep(1.0 if target == "zenoh" else 2.0)  # DDS matching takes longer
    subscriber.counting.set()
    before = floor.state()
    sent = publish(bus, seconds, rate_hz, stamped)
    settle(lambda: subscriber.count >= sent, 2.0)  # what was queued drains: at most 2 s
    after = floor.state()
    subscriber.counting.clear()
    floor.stop()
    subscriber.close()
    bus.close()
    received = after["count"] - before["count"]
    result = {
        "delivered": 100.0 * subscriber.count / max(sent, 1),
        "cpu_us_per_message": (after["cpu"] - before["cpu"]) / max(received, 1) * 1e6,
        "sent": float(sent),
        **(subscriber.latency_us() if isinstance(subscriber, Counting) else {}),
    }
    print(f"   floor {variant} ({target}) delivered {result['delivered']:6.2f}% of {sent} messages, floor CPU "
          f"{result['cpu_us_per_message']:6.1f} us/message ({received:.0f} received)", flush=True)  # fmt: skip
    return result


def at_rate(rate_hz: float) -> dict[str, Callable[[Path, float, str], dict[str, float]]]:
    """The floor onto Zenoh and onto DDS at `rate_hz` per channel, as `compare`'s other runners."""

    def runner(target: str) -> Callable[[Path, float, str], dict[str, float]]:
        return lambda folder, seconds, endpoint: run_floor(
            folder, seconds, endpoint, rate_hz, target, cheapest
        )

    # The cheapest variant in instructions a message (bench/instructions.py: 19.9k, against 21.2k
    # for handle_timeout in a thread), fixed here so these rows need no run of every variant.
    cheapest = "handle"
    return {target: runner(target) for target in ("zenoh", "dds")}


def candidates() -> dict[str, Callable[[Path, float, str], dict[str, float]]]:
    """Every floor variant and the minimal loop, as `compare`'s other runners (named floor:VARIANT)."""

    def runner(variant: str) -> Callable[[Path, float, str], dict[str, float]]:
        return lambda folder, seconds, endpoint: run_floor(folder, seconds, endpoint, variant=variant)

    return {f"floor:{variant}": runner(variant) for variant in (*VARIANTS, MINIMAL)}


def floors(best: dict[str, dict[str, float]]) -> tuple[str, float]:
    """The cheapest floor variant of `compare`'s figures (not the minimal loop: it checks them), and its CPU per message."""
    variant = min(VARIANTS, key=lambda name: best[f"floor:{name}"]["cpu_us_per_message"])
    return variant, best[f"floor:{variant}"]["cpu_us_per_message"]


def route_at(route: str, rate_hz: float) -> Runner:
    """A bridge route of bench/lcm_routes.py (relay, lcm_bus, or dds: lcm_bus onto DDS) at `rate_hz`
    per channel, as `compare`'s other runners."""
    return lambda folder, seconds, endpoint: run(route, folder, seconds, endpoint, rate_hz)


# The goals: the relay route within 1.5x of the floor's CPU per message, `lcm_bus` within 2x.
GOALS = {"relay": 1.5, "lcm_bus": 2.0}
TARGETS = {"zenoh": "Zenoh", "dds": "ROS 2 over DDS (rclpy)"}


def measures(size: Size = Size.FULL) -> list[Measure]:
    """The floor's candidates, the cheapest as the floor, checked against a minimal loop written
    from scratch; the bridge's CPU per message on its relay and lcm_bus routes beside the floor's
    onto the same target, at 10,000 and 30,000 messages a second, onto Zenoh and DDS (relay: Zenoh
    alone, its LCM bytes are no ROS 2 type), with what each delivered; latency at 10,000 a second."""
    seconds = size.pick(full=10.0, quick=4.0, smoke=0.5)
    rounds = size.pick(full=2, quick=1, smoke=1)
    slow = compare(seconds, rounds, others={
        **candidates(), "floor@dds": at_rate(RATE_HZ)["dds"], "lcm_bus@dds": route_at("dds", RATE_HZ)})  # fmt: skip
    variant, floor = floors(slow)
    minimal = slow[f"floor:{MINIMAL}"]["cpu_us_per_message"]
    setup = f"{len(CHANNELS)} channels at {RATE_HZ:g} Hz onto Zenoh, pinned to one core"
    rows = [Measure(f"floor: CPU per message of a bare lcm.subscribe('.*') -> Zenoh put process, the cheapest of its "
                    f"variants ({variant}), {setup}", floor, None, "us", "none (reported)", None),
            Measure(f"floor: the bench's floor against a minimal loop written from scratch (bench/minimal_floor.py: "
                    f"lc.handle() in the main thread), {setup}", floor, minimal, "us", "within 20%",
                    abs(floor / max(minimal, 1e-9) - 1) <= 0.2)]  # fmt: skip
    for name in VARIANTS:
        rows.append(Measure(f"floor: variant {name} ({VARIANT_WORDS[name]}), CPU per message, {setup}",
                            slow[f"floor:{name}"]["cpu_us_per_message"], floor, "us", "none (reported)", None))  # fmt: skip
    # Per rate and target: the floor, then each route's CPU per message beside it and what it delivered.
    fast = compare(seconds, 1, routes=(), others={
        "floor@zenoh": at_rate(FAST_HZ)["zenoh"], "floor@dds": at_rate(FAST_HZ)["dds"],
        "relay": route_at("relay", FAST_HZ), "lcm_bus": route_at("lcm_bus", FAST_HZ),
        "lcm_bus@dds": route_at("dds", FAST_HZ)})  # fmt: skip
    slow["floor@zenoh"] = slow[f"floor:{variant}"]
    for rate_hz, figures in ((RATE_HZ, slow), (FAST_HZ, fast)):
        for target, words in TARGETS.items():
            where = f"{rate_hz * len(CHANNELS):,.0f} lcmt_iiwa_status messages/s (20 channels) onto {words}, pinned"
            base = figures[f"floor@{target}"]
            rows.append(Measure(f"floor: delivered by the bare process, {where}", base["delivered"], None, "%",
                                "none: what any Python process on the core carries", None))  # fmt: skip
            rows.append(Measure(f"floor: its CPU per message, {where}", base["cpu_us_per_message"], None, "us",
                                "none (reported)", None))  # fmt: skip
            for route, goal in GOALS.items():
                if route == "relay" and target == "dds":
                    continue
                ours = figures[route if target == "zenoh" else f"{route}@{target}"]
                ratio = ours["cpu_us_per_message"] / max(base["cpu_us_per_message"], 1e-9)
                rows.append(Measure(f"floor: bridge's {route} route CPU per message (baseline: the floor's), {where}",
                                    ours["cpu_us_per_message"], base["cpu_us_per_message"], "us",
                                    f"<= {goal:g}x the floor's", ratio <= goal))  # fmt: skip
                rows.append(Measure(f"floor: delivered by the bridge's {route} route, {where}", ours["delivered"],
                                    base["delivered"], "%", ">= 99.9%", ours["delivered"] >= 99.9))  # fmt: skip
    for route in GOALS:
        for quantile in ("p50", "p99"):
            rows.append(Measure(f"floor: latency {quantile}, LCM publish -> Zenoh subscriber, bridge's {route} route "
                                f"(baseline: the floor), {setup}", slow[route].get(f"latency_{quantile}_us", math.nan),
                                slow[f"floor:{variant}"].get(f"latency_{quantile}_us", math.nan), "us",
                                "none (reported)", None))  # fmt: skip
    return rows


VARIANT_WORDS = {
    "handle": "lc.handle() in the main thread, queue unbounded",
    "handle_timeout": "lc.handle_timeout(100) in the main thread, queue unbounded",
    "thread": "lc.handle_timeout(100) in a thread, the main thread waiting on stdin, queue unbounded",
    "handle_queue30": "lc.handle() in the main thread, LCM's default queue of 30",
}


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument(
        "--rate-hz", type=float, help=f"per channel: the floor alone at this rate (issue 42: {FAST_HZ:g})"
    )
    parser.add_argument(
        "--serve", nargs=4, metavar=("URL", "ENDPOINT", "TARGET", "VARIANT"), help=argparse.SUPPRESS
    )
    args = parser.parse_args()
    if args.serve:
        serve(*args.serve)
        return
    if args.rate_hz:
        for target, figures in compare(args.seconds, 1, others=at_rate(args.rate_hz), routes=()).items():
            print(f"   {target:<8} " + ", ".join(f"{key} {value:.4g}" for key, value in figures.items()))
        return
    best = compare(args.seconds, args.rounds, others=candidates())
    variant, floor = floors(best)
    print(
        f"\nbest of the rounds (CPU per message, as a multiple of the floor's: {variant}; latency at 10k/s):"
    )
    for route, figures in best.items():
        cpu = figures["cpu_us_per_message"]
        latency = (
            f"p50 {figures.get('latency_p50_us', 0):6.0f} us, p99 {figures.get('latency_p99_us', 0):6.0f} us"
        )
        print(
            f"   {route:<22} {cpu:7.1f} us  {cpu / floor:5.2f}x  delivered {figures['delivered']:6.2f}%  {latency}"
        )


if __name__ == "__main__":
    main()
