"""`viewer-bridge play LOG`: the router fed by an LCM log under a playback clock instead of the bus.

The log is indexed once (viewer_bridge/transports/lcm_log_index.py), then played
(viewer_bridge/transports/lcm_playback.py) to the config's routes, and with `--lcm-out URL` onto
an LCM bus too. A Foxglove server of the config drives the clock from its playback bar
(viewer_bridge/transports/foxglove_playback.py), and on a terminal the keys do
(viewer_bridge/cli/play_keys.py); with neither, `play` ends with the log.
"""

from __future__ import annotations

import argparse
import logging
import signal
from pathlib import Path

from viewer_bridge.cli.arguments import (
    AddCommand,
    input_file,
    lcm_source,
    non_negative,
    positive,
    worker_count,
)
from viewer_bridge.cli.play_keys import keys
from viewer_bridge.cli.run import stats_options, status_view
from viewer_bridge.config.options import RunOptions, config_of
from viewer_bridge.errors import UsageError
from viewer_bridge.router.router import Router
from viewer_bridge.transports.lcm import Publisher
from viewer_bridge.transports.lcm_log_index import LogIndex
from viewer_bridge.transports.lcm_playback import LogPlayer
from viewer_bridge.transports.lcm_url import log_to_write
from viewer_bridge.util.progress import progress


def add_command(add: AddCommand) -> None:
    """The `play` command's arguments, on the parser `add` makes."""
    play = add(
        "play",
        help="play an LCM log to the router's outputs under a clock Foxglove's timeline drives "
        "(pause, speed, seek), optionally onto an LCM bus too",
    )
    play.add_argument("log", type=input_file, help="the LCM log to play")
    play.add_argument("-c", "--config", help="a YAML config (default: the built-in one)")
    play.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TRANSPORT.KEY=VALUE",
        help="override a transport setting, e.g. foxglove.port=9000 (repeatable)",
    )
    play.add_argument(
        "--lcm-out",
        type=lcm_source,
        metavar="URL",
        help="also publish each played event on this LCM bus, as lcm-logplayer does (the bridge never "
        "reads it back); default: none",
    )
    play.add_argument("--paused", action="store_true", help="start paused (Foxglove's play button starts it)")
    play.add_argument(
        "--speed", type=positive, default=1.0, metavar="S", help="playback speed (2: twice as fast)"
    )
    play.add_argument(
        "--start", type=non_negative, default=0.0, metavar="S", help="start S seconds after the log's start"
    )
    play.add_argument("--loop", action="store_true", help="play from the start again at the end")
    stats_options(play)
    play.add_argument(
        "--workers",
        type=worker_count,
        metavar="N",
        help="worker processes (play runs its routes in this process: 1 only)",
    )
    play.add_argument(
        "-q", "--quiet", action="store_true", help="print only warnings and errors (no route table or lines)"
    )


def index_log(log: str, command: str, quiet: bool = False) -> LogIndex:
    """The log's index; while a big log is indexed, its progress (a bar on a terminal, a line per
    tenth on a pipe: the command line's one way of showing long work)."""
    path = Path(log)
    size = path.stat().st_size if path.is_file() else None  # else LogIndex.build says what is wrong
    if quiet or not size:
        return LogIndex.build(path)
    megabytes = size / 1e6
    with progress(f"viewer-bridge {command}", f"indexing {log}", size,
                  lambda done: f"{done / 1e6:,.0f} of {megabytes:,.0f} MB") as advance:  # fmt: skip
        indexed = 0

        def told(done: int, total: int) -> None:  # the index tells how far it is, the bar how much more
            nonlocal indexed
            advance(done - indexed)
            indexed = done

        return LogIndex.build(path, told)


def run_options(args: argparse.Namespace) -> RunOptions:
    """What `play`'s command line says about the config, as one record."""
    return RunOptions(config=args.config, this_install=True, settings=args.set)


def run(args: argparse.Namespace) -> int:
    """Index the log, then route what it plays until it ends (nothing to seek with), Ctrl-C or SIGTERM."""
    if args.workers is not None and args.workers > 1:
        raise UsageError(f"--workers {args.workers}: play runs its routes in one process (--workers 1)")
    if args.lcm_out and log_to_write(args.lcm_out) is None and args.lcm_out.startswith("file://"):
        raise UsageError(f"--lcm-out {args.lcm_out}: a log to write is file://PATH?mode=w")
    # indexed before the route table takes the terminal: its progress line is a line of its own
    index = index_log(args.log, "play", quiet=args.quiet)
    if len(index) == 0:
        raise UsageError(f"{args.log} holds no whole LCM event: nothing to play")
    try:
        view = status_view(args.quiet)
    except BaseException:
        index.close()
        raise
    try:
        config = config_of(run_options(args))
        if "lcm" not in config.transports():
            raise UsageError(
                f"no route of {args.config or 'the built-in config'} reads LCM: nothing to play to"
            )
        length_s = (index.last_us - index.first_us) / 1e6
        if args.start > length_s:
            logging.getLogger("viewer_bridge").warning(
                "viewer-bridge play: --start %g is past the log's end (%.3f s long): starting at its end",
                args.start,
                length_s,
            )
        player = LogPlayer(
            index,
            speed=args.speed,
            start_us=index.first_us + round(args.start * 1e6),
            paused=args.paused,
            loop=args.loop,
            out=Publisher(args.lcm_out) if args.lcm_out else None,
        )
        router = Router(
            config,
            stats_json=args.stats_json,
            stats_period=args.stats_period,
            view=view,
            timeline=player,
        )
    except BaseException:
        view.close()
        index.close()
        raise
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda number, frame: router.stop())
    with keys(player):  # on a terminal: space, left, right, + and -
        router.run()
    return 0
