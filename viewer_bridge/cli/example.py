"""`viewer-bridge example NAME`: one of the pydrake example simulations (viewer_bridge/examples/)."""

from __future__ import annotations

import argparse

from viewer_bridge.cli.arguments import AddCommand, lcm_source, positive
from viewer_bridge.errors import UsageError
from viewer_bridge.examples.catalog import EXAMPLES, drake_missing, run_example
from viewer_bridge.transports.lcm import DEFAULT_URL


def add_command(add: AddCommand) -> None:
    """The `example` command's arguments, on the parser `add` makes."""
    example = add(
        "example",
        help="run an example pydrake simulation that publishes over LCM (needs Drake: "
        "pip install 'viewer-bridge[drake]')",
        description="Example simulations: " + "; ".join(f"{name}: {what}" for name, what in EXAMPLES.items()),
    )
    example.add_argument("name", choices=list(EXAMPLES), help="which example")
    example.add_argument(
        "--duration", type=positive, default=10.0, metavar="S", help="seconds to simulate, in real time"
    )
    example.add_argument(
        "--lcm-url",
        type=lcm_source,
        default=DEFAULT_URL,
        metavar="URL",
        help="LCM URL to publish on (file://LOG?mode=w records a log)",
    )


def run(args: argparse.Namespace) -> int:
    """Simulate in real time for --duration; without pydrake, one line saying how to install it."""
    if missing := drake_missing():
        raise UsageError(missing)
    print(f"example {args.name}: publishing on {args.lcm_url} for {args.duration:g} s", flush=True)
    run_example(args.name, args.lcm_url, args.duration)
    print(f"example {args.name}: done")
    return 0
