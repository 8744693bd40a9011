"""Benchmark: instructions per message, the measure that a busy machine does not move.

Run: .venv/bin/python bench/instructions.py [--messages 2000] [--subjects relay lcm_bus handle ...]

Each subject (the bridge's `relay` and `lcm_bus` routes of bench/lcm_routes.py, a floor variant of
bench/floor.py, or `minimal`, bench/minimal_floor.py) runs under valgrind's callgrind, which counts
the instructions every thread of the process executes (in user space: not the kernel's), beside a
Zenoh router and subscriber in this process. After a warm-up (every channel's publisher made, the
lazy route awake) the count is zeroed, `--messages` lcmt_iiwa_status messages go out on 20
channels at `--rate` a second, and the count is read when the subject has them all; then the same
wall time again with no message, whose count (timers, the stats file) is taken off. The figure is
what is left, per message the subject received. Wall-clock and CPU time on a shared machine move
with its load; this does not, so it is what a change to the message path is judged by. Under
callgrind everything runs some 50 times slower, so the rate is low: each message is read alone.
"""

from __future__ import annotations

import argparse
import glob
import os
import subprocess
import tempfile
import time
from pathlib import Path

from common import iiwa_status_bytes, paced
from floor import MINIMAL, VARIANTS, Floor
from lcm_routes import CHANNELS, Counting, bus_config
from router import URL, Bridge
from zenoh_routes import _free_port, zenoh_session

from viewer_bridge.transports.lcm import LcmBus

ROUTES = ("relay", "lcm_bus")


def _total(out: str, pid: int) -> int:
    """The instructions of callgrind's newest dump of `pid`."""
    newest = max(glob.glob(f"{out}.{pid}*"), key=os.path.getmtime)
    for line in Path(newest).read_text().splitlines():
        if line.startswith(("totals:", "summary:")):
            return int(line.split()[1])
    raise RuntimeError(f"{newest}: no totals")


def _control(flag: str, pid: int) -> None:
    subprocess.run(["callgrind_control", flag, str(pid)], check=True, capture_output=True, timeout=120)


def measure(
    subject: str, messages: int, rate: float, folder: Path, endpoint: str, source: Path | None = None
) -> dict[str, float]:
    """`subject` under callgrind: instructions per message received, net of its idle count; a
    route runs `source`'s checkout of the bridge when given (a baseline)."""
    out = str(folder / f"callgrind.{subject}{'' if source is None else '.baseline'}")
    prefix = ("valgrind", "--tool=callgrind", f"--callgrind-out-file={out}.%p", "--dump-instr=no")
    is_route = subject in ROUTES
    # No stats file while it counts (its percentiles each second would be most of an idle count):
    # what the subject carried is what the subscriber received.
    bridge = Bridge(bus_config(endpoint, subject), folder, 0, source, prefix, 3600.0) if is_route else None
    floor = None if is_route else Floor(endpoint, "zenoh", subject, prefix=prefix)
    pid = bridge.process.pid if bridge is not None else floor.process.pid  # type: ignore[union-attr]
    domain = int(os.environ.get("ROS_DOMAIN_ID") or 0)
    subscriber = Counting(endpoint, "lcm" if subject != "lcm_bus" else f"{domain}/lcm")
    subscriber.counting.set()
    bus = LcmBus(URL)
    data = iiwa_status_bytes()
    send = lambda index: bus.publish(CHANNELS[index % len(CHANNELS)], data)  # noqa: E731

    def settled(count: int, at_most: float) -> None:
        """Until the subscriber has `count` messages, or has had none for 5 s, at most `at_most` s."""
        deadline = time.monotonic() + at_most
        seen, since = subscriber.count, time.monotonic()
        while subscriber.count < count and time.monotonic() < deadline and time.monotonic() - since < 5.0:
            time.sleep(0.1)
            if subscriber.count != seen:
                seen, since = subscriber.count, time.monotonic()

    try:
        time.sleep(2.0)
        # Warm-up: every channel's publisher, the lazy route awake, each lane's translator and codec
        # made (under callgrind that takes a while): a second of messages at a time, until one
        # second's all arrive (a lazy route's skipped ones do not), at most 180 s. Else what is
        # counted has the warm-up's work in it, and its late messages.
        deadline = time.monotonic() + 180.0
        while time.monotonic() < deadline:
            before = subscriber.count
            warm = paced(send, 0, rate, 1.0)
            settled(before + warm, 60.0)
            if subscriber.count - before >= warm:
                break
        time.sleep(2.0)
        before = subscriber.count
        _control("-z", pid)
        started = time.monotonic()
        sent = paced(send, messages, rate, messages / rate)
        settled(before + sent, 60.0)
        _control("-d", pid)
        busy = _total(out, pid)
        spent = time.monotonic() - started
        count = subscriber.count - before
        _control("-z", pid)
        time.sleep(spent)
        _control("-d", pid)
        idle = _total(out, pid)
    finally:
        subscriber.close()
        bus.close()
        if bridge is not None:
            bridge.stop()
        else:
            floor.stop()  # type: ignore[union-attr]
    result = {
        "instructions_per_message": (busy - idle) / max(count, 1),
        "received": float(count),
        "sent": float(sent),
        "delivered": 100.0 * count / max(sent, 1),
        "idle_share": idle / max(busy, 1),
    }
    print(f"   {subject:<15} {result['instructions_per_message']:10,.0f} instructions/message "
          f"({count} of {sent} received, {result['delivered']:.1f}% delivered, idle {100 * idle / busy:.1f}% "
          "of the count taken off)", flush=True)  # fmt: skip
    return result


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--messages", type=int, default=2000)
    parser.add_argument("--rate", type=float, default=200.0, help="messages a second, all channels")
    parser.add_argument("--subjects", nargs="+", default=[*ROUTES, *VARIANTS, MINIMAL])
    parser.add_argument("--source", type=Path, help="the routes run this checkout's bridge too (a baseline)")
    parser.add_argument("--keep", type=Path, help="callgrind's files go here (for callgrind_annotate), kept")
    args = parser.parse_args()
    everywhere = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {1})
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    router = zenoh_session("router", {"listen": [endpoint]})
    try:
        with tempfile.TemporaryDirectory() as name:
            folder = Path(name) if args.keep is None else args.keep
            folder.mkdir(parents=True, exist_ok=True)
            for subject in args.subjects:
                measure(subject, args.messages, args.rate, folder, endpoint)
                if args.source is not None and subject in ROUTES:
                    print(f"   ... the same with {args.source}'s bridge:")
                    measure(subject, args.messages, args.rate, folder, endpoint, args.source)
    finally:
        router.close()  # type: ignore[no-untyped-call]
        os.sched_setaffinity(0, everywhere)


if __name__ == "__main__":
    main()
