"""`viewer-bridge dump`: an LCM log, or a live LCM bus, as text or JSON (rendered by `cli/dump.py`)."""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Iterator

from viewer_bridge.cli.arguments import AddCommand, input_file, lcm_source, lcm_types_option, positive, regex
from viewer_bridge.cli.dump import as_json, as_text
from viewer_bridge.errors import UsageError
from viewer_bridge.examples.demo import run_demo
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.transports.lcm import DEFAULT_URL, LcmEvent, Subscription, read_log


def add_command(add: AddCommand) -> None:
    """The `dump` command's arguments, on the parser `add` makes."""
    dump = add("dump", help="decode an LCM log (or a live LCM bus) to text or JSON")
    dump.add_argument("log", nargs="?", type=input_file, help="an .lcmlog file (omit with --live)")
    dump.add_argument(
        "--live",
        nargs="?",
        const=DEFAULT_URL,
        type=lcm_source,
        metavar="URL",
        help=f"listen on an LCM URL (default {DEFAULT_URL})",
    )
    dump.add_argument(
        "--channel", default=".*", type=regex, metavar="REGEX", help="only channels that fully match REGEX"
    )
    dump.add_argument("--json", action="store_true", help="one JSON object per message")
    lcm_types_option(dump)
    dump.add_argument("--duration", type=positive, help="with --live: stop after this many seconds")
    dump.add_argument(
        "--demo", action="store_true", help="with --live: also publish the demo scene on the same URL"
    )


def run(args: argparse.Namespace) -> int:
    """Print each message of the log or the bus, one per line, until the end, --duration or Ctrl-C."""
    if (args.log is None) == (args.live is None):
        raise UsageError("give either a log file or --live [URL]")
    stop = threading.Event()
    demo: threading.Thread | None = None
    events: Iterator[LcmEvent]
    if args.live is not None:
        subscription = Subscription(args.live, args.channel)  # before the demo's first message
        if args.demo:
            demo = threading.Thread(
                target=run_demo, args=(args.live, args.duration), kwargs={"stop": stop}, daemon=True
            )
            demo.start()
        events = subscription.events(args.duration)
    else:
        events = read_log(args.log, args.channel)
    render = as_json if args.json else as_text
    types = TypeLibrary.load(args.lcm_types)
    try:
        for event in events:
            print(render(event, types), flush=True)
    except KeyboardInterrupt:
        pass
    except BrokenPipeError:
        sys.stderr.close()  # e.g. piped into `head`: stop quietly
    finally:
        stop.set()
        if demo is not None:
            demo.join()
    return 0
