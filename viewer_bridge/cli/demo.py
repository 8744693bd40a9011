"""`viewer-bridge demo`: the demo scene (viewer_bridge/examples/demo.py) published over LCM."""

from __future__ import annotations

import argparse
import signal
import threading

from viewer_bridge.cli.arguments import AddCommand, lcm_source, positive
from viewer_bridge.examples.demo import run_demo
from viewer_bridge.transports.lcm import DEFAULT_URL


def add_command(add: AddCommand) -> None:
    """The `demo` command's arguments, on the parser `add` makes."""
    demo = add("demo", help="publish a moving Drake-like scene with every shape over LCM")
    demo.add_argument("--url", type=lcm_source, default=DEFAULT_URL, help="LCM URL to publish on")
    demo.add_argument(
        "--duration", type=positive, help="stop after this many seconds (default: until Ctrl-C)"
    )
    demo.add_argument("--rate", type=positive, default=60.0, help="draw messages per second")


def run(args: argparse.Namespace) -> int:
    """Publish until --duration or Ctrl-C, then say how many draw messages went out."""
    stop = threading.Event()  # Ctrl-C or SIGTERM: the summary line, then exit 0
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda *_: stop.set())
    until = f"for {args.duration:g} s" if args.duration else "until Ctrl-C"
    print(f"publishing the demo scene on {args.url} at {args.rate:g} Hz, {until}", flush=True)
    sent = run_demo(args.url, args.duration, args.rate, stop=stop)
    print(f"published {sent} draw messages on {args.url}")
    return 0
