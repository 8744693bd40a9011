"""Benchmark: any LCM type through `run`, 20 channels of `lcmt_iiwa_status` at 500 Hz each.

Run: .venv/bin/python bench/lcm_routes.py [--seconds 10]

The bridge runs as a process pinned to one core (CPU 0) with the built-in zenoh config's
`lcm_bus` route (`lcm_to_ros`: each channel to /lcm/<channel> as drake_lcm_msgs/msg/LcmtIiwaStatus
CDR, in rmw_zenoh's format); this process runs on the other core: a Zenoh router (eclipse-zenoh in
router mode on 127.0.0.1), the LCM publisher (20 channels IIWA_STATUS_00 ... _19, 10,000 messages
a second in all, as pydrake's lcm-gen'd class encodes them) and one Zenoh subscriber on every
topic. Zenoh, not DDS: DDS needs the types' interfaces built, which this branch does not do.

Baseline, same run: the same channels through an `lcm_relay` route onto the same Zenoh session
(the bytes as they are: no type lookup, no transcoding). Reported per route: delivered (messages
that reached the subscriber, of those sent; the first second, while the lazy route wakes, left
out) and the bridge's CPU time per message it received (user + system, /proc/PID/stat).

Delivery at a rate (`--rate-hz`, per channel; issue 42's goal is 1500 Hz, 30,000 messages a
second): the built-in zenoh config's `lcm_bus` to a Zenoh subscriber as above, and the built-in
default config's `lcm_bus` (the ros transport: ROS 2 over DDS, drake_lcm_msgs built) to an rclpy
subscriber on every topic (`--dds`; raw, so the count is not rclpy's deserialisation; in a process
of its own). The subscribers share the other core with the publisher and the Zenoh router, so at
high rates what they keep up with bounds what is seen delivered: the DDS row's bridge-published
figure (the route's messages out, of those sent) says what the bridge did.
"""

from __future__ import annotations

import argparse
import os
import struct
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from common import DdsCounter, Measure, Size, iiwa_status_bytes, settle
from router import URL, Bridge
from zenoh_routes import _free_port, zenoh_session

from viewer_bridge.config.bridge import BUILTIN_CONFIGS
from viewer_bridge.transports.lcm import LcmBus

CHANNELS = tuple(f"IIWA_STATUS_{index:02d}" for index in range(20))
RATE_HZ = 500.0  # per channel
FAST_HZ = 1500.0  # per channel: issue 42's 30,000 messages a second
RELAY = """\
  - name: relay
    source: {transport: lcm, name: "(IIWA_STATUS_.*)"}
    translator: lcm_relay
    destination: {transport: zenoh, name: "{1}"}
    qos: {depth: 100}
    rate: {policy: all}
"""


def bus_config(endpoint: str, route: str) -> str:
    """The built-in zenoh config's `lcm_bus` route as it ships (or the relay baseline), alone."""
    if route == "relay":
        return f"zenoh: {{connect: [{endpoint}]}}\nroutes:\n{RELAY}"
    [bus] = [r for r in yaml.safe_load(BUILTIN_CONFIGS["zenoh"])["routes"] if r["name"] == "lcm_bus"]
    return yaml.safe_dump({"zenoh": {"connect": [endpoint]}, "routes": [bus]})


class Counting:
    """One Zenoh subscriber on every key under `prefix`; counts arrivals while `counting` is set.

    With `stamp` (the message's `utime` as `publish(stamped=True)` sets it: a struct format and its
    offset in what arrives), it keeps each arrival's latency from the publisher's `publish` too."""

    def __init__(self, endpoint: str, prefix: str, stamp: tuple[str, int] | None = None) -> None:
        self.session = zenoh_session("client", {"connect": [endpoint]})
        self.counting = threading.Event()
        self.count = 0
        self.latencies_us: list[int] = []
        self._stamp = None if stamp is None else struct.Struct(stamp[0])
        self._offset = 0 if stamp is None else stamp[1]
        self._held = self.session.declare_subscriber(f"{prefix}/**", self._arrived)

    def _arrived(self, sample: Any) -> None:
        if self.counting.is_set():
            self.count += 1
            if self._stamp is not None:
                [sent] = self._stamp.unpack_from(sample.payload.to_bytes(), self._offset)
                self.latencies_us.append(time.time_ns() // 1000 - sent)

    def latency_us(self) -> dict[str, float]:
        """p50 and p99 of the latencies kept (empty without `stamp`)."""
        if not self.latencies_us:
            return {}
        p50, p99 = np.percentile(self.latencies_us, [50, 99])
        return {"latency_p50_us": float(p50), "latency_p99_us": float(p99)}

    def close(self) -> None:
        del self._held
        self.session.close()  # type: ignore[no-untyped-call]


# Where an lcmt_iiwa_status's `utime` is: in its LCM bytes (after the 8-byte fingerprint, big-endian)
# and in its CDR (after the 4-byte encapsulation header, little-endian), for `Counting`'s latency.
LCM_STAMP = (">q", 8)
CDR_STAMP = ("<q", 4)


def publish(bus: LcmBus, seconds: float, rate_hz: float = RATE_HZ, stamped: bool = False) -> int:
    """Every channel at `rate_hz` for `seconds`, round-robin, paced by the clock; returns messages
    sent. `stamped`: each message's `utime` is the time it is published (microseconds since the
    epoch), for the subscriber's latency."""
    data = iiwa_status_bytes()
    head, tail = data[: LCM_STAMP[1]], data[LCM_STAMP[1] + 8 :]
    stamp = struct.Struct(LCM_STAMP[0]).pack
    period = 1.0 / (rate_hz * len(CHANNELS))
    start = time.perf_counter()
    sent = 0
    while time.perf_counter() - start < seconds:
        due = start + sent * period
        while time.perf_counter() < due:
            pass
        if stamped:
            data = head + stamp(time.time_ns() // 1000) + tail
        bus.publish(CHANNELS[sent % len(CHANNELS)], data)
        sent += 1
    return sent


def dds_counter() -> DdsCounter:
    """A raw rclpy subscriber on every channel's topic, /lcm/<channel>, in a process of its own."""
    return DdsCounter(
        {channel: (f"/lcm/{channel}", "drake_lcm_msgs/msg/LcmtIiwaStatus") for channel in CHANNELS}
    )


def dds_config() -> str:
    """The built-in default config's `lcm_bus` route (LCM -> ROS 2 over DDS) as it ships, alone."""
    [bus] = [r for r in yaml.safe_load(BUILTIN_CONFIGS["default"])["routes"] if r["name"] == "lcm_bus"]
    return yaml.safe_dump({"routes": [bus]})


def run(
    route: str, folder: Path, seconds: float, endpoint: str, rate_hz: float = RATE_HZ
) -> dict[str, float]:
    """`route` (relay, lcm_bus, or dds: lcm_bus onto ROS 2 over DDS) at `rate_hz` per channel."""
    domain = int(os.environ.get("ROS_DOMAIN_ID") or 0)
    bridge = Bridge(dds_config() if route == "dds" else bus_config(endpoint, route), folder, core=0)
    stamped = route != "dds" and rate_hz <= RATE_HZ  # latency at 10,000 a second; none at 30,000
    stamp = (LCM_STAMP if route == "relay" else CDR_STAMP) if stamped else None
    subscriber: Counting | DdsCounter = (
        dds_counter()
        if route == "dds"
        else Counting(endpoint, "lcm" if route == "relay" else f"{domain}/lcm", stamp)
    )
    bus = LcmBus(URL)
    time.sleep(1.0)
    publish(bus, 1.0, rate_hz)  # the lazy route wakes, each channel's publisher appears
    time.sleep(1.0 if route != "dds" else 2.0)  # DDS matching takes longer
    subscriber.counting.set()
    cpu_before = bridge.cpu_seconds()
    in_before, out_before = _messages(bridge.snapshot())
    sent = publish(bus, seconds, rate_hz, stamped)
    # What was queued drains, and the stats file is written again (every second): until the
    # subscriber has every message and the stats count them all, at most 2 s.
    settle(lambda: subscriber.count >= sent and _messages(bridge.snapshot())[0] - in_before >= sent, 2.0)
    cpu = bridge.cpu_seconds() - cpu_before
    messages_in, messages_out = _messages(bridge.snapshot())
    received, published = messages_in - in_before, messages_out - out_before
    subscriber.counting.clear()
    bridge.stop()
    subscriber.close()
    bus.close()
    result = {
        "delivered": 100.0 * subscriber.count / max(sent, 1),
        "published": 100.0 * published / max(sent, 1),
        "cpu_us_per_message": cpu / max(received, 1) * 1e6,
        "sent": float(sent),
        **(subscriber.latency_us() if isinstance(subscriber, Counting) else {}),
    }
    print(f"   {route:<8} delivered {result['delivered']:6.2f}% of {sent} messages (the bridge published "
          f"{result['published']:6.2f}%), bridge CPU "
          f"{result['cpu_us_per_message']:6.1f} us/message ({received} received)", flush=True)  # fmt: skip
    return result


def _messages(stats: dict[str, Any]) -> tuple[int, int]:
    """The route's messages in and out so far (the busiest route's)."""
    routes = [r for name, r in stats.items() if name != "transports"]
    return max((r["messages_in"] for r in routes), default=0), max(
        (r["messages_out"] for r in routes), default=0
    )


Runner = Callable[[Path, float, str], dict[str, float]]  # (folder, seconds, Zenoh endpoint) -> figures


def compare(
    seconds: float,
    rounds: int = 2,
    others: dict[str, Runner] | None = None,
    routes: tuple[str, ...] = ("lcm_bus", "relay"),
) -> dict[str, dict[str, float]]:
    """`routes` (and `others`, by name: bench/floor.py's floor), `rounds` times interleaved;
    per figure, the better round."""
    others = others or {}
    everywhere = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {1})  # the publisher, the Zenoh router and the subscriber; the bridge gets CPU 0
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = zenoh_session("router", {"listen": [endpoint]})
    best: dict[str, dict[str, float]] = {}
    try:
        with tempfile.TemporaryDirectory() as name:
            for _ in range(rounds):
                for route in (*routes, *others):
                    if route in others:
                        result = others[route](Path(name), seconds, endpoint)
                    else:
                        result = run(route, Path(name), seconds, endpoint)
                    kept = best.setdefault(route, result)
                    for key, value in result.items():
                        kept[key] = (max if key in ("delivered", "published") else min)(
                            kept.get(key, value), value
                        )
    finally:
        router.close()  # type: ignore[no-untyped-call]
        os.sched_setaffinity(0, everywhere)
    return best


def delivery(seconds: float, rate_hz: float, dds: bool) -> dict[str, dict[str, float]]:
    """The lcm_bus route onto Zenoh (and onto DDS with `dds`) at `rate_hz` per channel."""
    others: dict[str, Runner] = {}
    if dds:
        others["dds"] = lambda folder, duration, endpoint: run("dds", folder, duration, endpoint, rate_hz)
    zenoh: Runner = lambda folder, duration, endpoint: run("lcm_bus", folder, duration, endpoint, rate_hz)  # noqa: E731
    return compare(seconds, 1, others={"zenoh": zenoh, **others}, routes=())


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Issue 31's throughput goal: >= 99% delivered through `run`, with the bridge's CPU per message;
    issue 42's: 30,000 messages a second >= 99.9% delivered onto Zenoh and onto DDS."""
    best = compare(size.pick(full=10.0, quick=4.0, smoke=0.5), size.pick(full=2, quick=1, smoke=1))
    ours, relay = best["lcm_bus"], best["relay"]
    setup = "20 channels of lcmt_iiwa_status at 500 Hz, Zenoh, bridge pinned"
    fast = delivery(size.pick(full=10.0, quick=4.0, smoke=0.5), FAST_HZ, dds=True)
    fast_setup = f"{FAST_HZ * len(CHANNELS):,.0f} lcmt_iiwa_status messages/s (20 channels), bridge pinned"
    return [
        Measure(f"lcm_routes: delivered onto Zenoh, {fast_setup}", fast["zenoh"]["delivered"], None,
                "%", ">= 99.9%", fast["zenoh"]["delivered"] >= 99.9),
        Measure(f"lcm_routes: delivered onto ROS 2 over DDS (rclpy), {fast_setup}", fast["dds"]["delivered"], None,
                "%", ">= 99.9%", fast["dds"]["delivered"] >= 99.9),
        Measure(f"lcm_routes: published onto DDS by the bridge (its route's messages out, of those sent), {fast_setup}",
                fast["dds"]["published"], None, "%", "none: where messages were lost", None),
        Measure(f"lcm_routes: delivered, {setup} (baseline: raw relay)", ours["delivered"], relay["delivered"],
                "%", ">= 99%", ours["delivered"] >= 99.0),
        Measure(f"lcm_routes: bridge CPU per message, {setup} (baseline: raw relay)", ours["cpu_us_per_message"],
                relay["cpu_us_per_message"], "us", "none (reported)", None),
    ]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument(
        "--rate-hz", type=float, help=f"per channel: delivery at this rate (issue 42: {FAST_HZ:g})"
    )
    parser.add_argument("--dds", action="store_true", help="with --rate-hz: onto ROS 2 over DDS too")
    args = parser.parse_args()
    rate = args.rate_hz or RATE_HZ
    print(f"20 channels of lcmt_iiwa_status at {rate:g} Hz for {args.seconds:.0f} s, bridge pinned to CPU 0")
    best = (
        delivery(args.seconds, args.rate_hz, args.dds) if args.rate_hz else compare(args.seconds, args.rounds)
    )
    print("\nbest of the rounds:")
    for route, figures in best.items():
        print(f"   {route:<8} " + ", ".join(f"{key} {value:.4g}" for key, value in figures.items()))


if __name__ == "__main__":
    main()
