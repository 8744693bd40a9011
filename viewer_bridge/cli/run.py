"""`viewer-bridge run`: the router, from a config and the command line's overrides of it."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading

from rich.console import Console

from viewer_bridge.cli.arguments import (
    AUTO,
    AddCommand,
    channel_regex,
    lcm_source,
    lcm_types_option,
    output_file,
    positive,
    topic_regex,
    worker_count_or_auto,
)
from viewer_bridge.config.bridge import BUILTIN_CONFIGS, BridgeConfig
from viewer_bridge.config.options import RunOptions, config_of
from viewer_bridge.errors import UsageError
from viewer_bridge.examples.demo import run_demo
from viewer_bridge.router.router import Router
from viewer_bridge.router.status import ConsoleLog, LiveTable, LogLines, StatusView
from viewer_bridge.router.workers import Workers, auto_workers
from viewer_bridge.transports.command_policy import COMMAND_FLAG
from viewer_bridge.transports.lcm import DEFAULT_URL
from viewer_bridge.transports.lcm_url import log_to_write
from viewer_bridge.util.words import counted


def add_command(add: AddCommand) -> None:
    """The `run` command's arguments, on the parser `add` makes (its --ros-args are split off
    before parsing, by `main`)."""
    run = add(
        "run",
        help="run the router: bridge Drake's LCM scene to ROS 2 (and back); --ros-args ... [--] as any ROS 2 node",
    )
    run.add_argument(
        "-c", "--config", help="a YAML config (default: the built-in one, see --print-default-config)"
    )
    run.add_argument("--print-default-config", action="store_true", help="print the built-in config and exit")
    run.add_argument(
        "--print-config",
        metavar="NAME",
        help=f"print a built-in config ({', '.join(BUILTIN_CONFIGS)}) and exit; use it as -c builtin:NAME",
    )
    run.add_argument(
        "--lcm-url",
        type=lcm_source,
        help="override the config's LCM URL (a log file or file://LOG?speed=S replays it)",
    )
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="TRANSPORT.KEY=VALUE",
        help="override a transport setting, e.g. foxglove.port=9000 or ros.namespace=/sim1, the "
        "commands section's, e.g. commands.max_age_ms=500, or a top-level key, e.g. time=sim (repeatable)",
    )
    lcm_types_option(run)
    run.add_argument(
        COMMAND_FLAG,
        action="append",
        default=[],
        type=channel_regex,
        metavar="REGEX",
        help="LCM channels (a regular expression matched against the whole name) that ROS 2 and Foxglove "
        "may command by publishing on /lcm_in/<channel> (repeatable; default: none, nothing is written)",
    )
    run.add_argument(
        "--ros-topics",
        action="append",
        default=[],
        type=topic_regex,
        metavar="REGEX",
        help="ROS 2 topics (a regular expression matched against the whole name, e.g. '/joint_states|/imu') "
        "to carry onto LCM, each on the channel named by the topic without its leading / (repeatable; "
        "default: none)",
    )
    stats_options(run)
    run.add_argument(
        "--duration", type=positive, metavar="S", help="stop after S seconds (default: until Ctrl-C)"
    )
    run.add_argument("--demo", action="store_true", help="also publish the demo scene on the LCM URL")
    run.add_argument(
        "--workers",
        type=worker_count_or_auto,
        metavar="N",
        help="run the routes on N worker processes, placed by their source (default: the config's "
        "workers, 1: all in this process); a route's worker: K pins it; Ctrl-C exits 130; auto: a "
        "worker per core left free once one is kept for the peers, at most one per group of routes "
        "that read different channels, at least 1",
    )
    run.add_argument(
        "-q", "--quiet", action="store_true", help="print only warnings and errors (no route table or lines)"
    )


def _worker_count(asked: int | str | None, config: BridgeConfig) -> int:
    """--workers N, or what `auto` counts (said in a line), or the config's `workers`."""
    if asked != AUTO:
        return int(asked or config.workers)
    chosen = auto_workers(config)
    logging.getLogger("viewer_bridge").info("viewer-bridge: %s", chosen.why())
    return chosen.workers


def stats_options(command: argparse.ArgumentParser) -> None:
    """The options of a command that runs routes and reports their stats (`run`, `play`)."""
    command.add_argument(
        "--stats-json",
        type=output_file(),
        metavar="PATH",
        help="write per-route stats as JSON every period and at exit",
    )
    command.add_argument(
        "--stats-period", type=positive, default=5.0, metavar="S", help="seconds between stats lines"
    )


def run(args: argparse.Namespace) -> int:
    """Print a built-in config, or route until --duration, Ctrl-C or SIGTERM."""
    if args.print_default_config or args.print_config:
        name = args.print_config or "default"
        if name not in BUILTIN_CONFIGS:
            raise UsageError(f"no built-in config {name!r} (known: {', '.join(BUILTIN_CONFIGS)})")
        print(BUILTIN_CONFIGS[name], end="")
        return 0
    view = status_view(args.quiet)
    try:
        options = run_options(args)  # the command line's say about the config, as one record
        config = config_of(options)
        if args.demo and log_to_write(_lcm_url(config)):
            raise UsageError(
                f"--demo: the routes would read the demo on {_lcm_url(config)}, a log LCM only writes; "
                "record the demo itself with `viewer-bridge demo --url URL`"
            )
        workers = _worker_count(args.workers, config)
        if workers > 1:  # the routes on worker processes, this one merging their stats
            router: Router | Workers = Workers(config, workers, args.stats_json, args.stats_period, view)
        else:
            router = Router(config, stats_json=args.stats_json, stats_period=args.stats_period, view=view)
    except BaseException:
        view.close()  # a live table leaves the screen before the error
        raise
    signals: list[int] = []  # which stopped the bridge: Ctrl-C stops workers with exit code 130

    def stop(number: int, _: object) -> None:
        signals.append(number)
        router.stop()

    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, stop)
    stop_demo = threading.Event()
    demo = None
    router.start()  # subscribed before the demo's first message
    if args.demo:
        demo = threading.Thread(
            target=run_demo, args=(_lcm_url(config), None), kwargs={"stop": stop_demo}, daemon=True
        )
        demo.start()
    try:
        router.run(args.duration)
    finally:
        stop_demo.set()
        if demo is not None:
            demo.join(timeout=2)
    if isinstance(router, Workers) and signal.SIGINT in signals:  # every worker stopped and waited for
        print(
            f"viewer-bridge run: interrupted: {counted(len(router.processes()), 'worker')} stopped",
            file=sys.stderr,
        )
        return 130
    return 0


def run_options(args: argparse.Namespace) -> RunOptions:
    """What `run`'s command line says about the config, as one record."""
    return RunOptions(
        config=args.config,
        this_install=True,
        lcm_types=args.lcm_types,
        allow_commands=args.allow_commands,
        ros_topics=args.ros_topics,
        lcm_url=args.lcm_url,
        settings=args.set,
        ros_args=args.ros_args,
    )


def status_view(quiet: bool) -> StatusView:
    """A live route table when stdout is a terminal; plain log lines on stderr otherwise."""
    level = logging.WARNING if quiet else logging.INFO
    if quiet or not sys.stdout.isatty():
        logging.basicConfig(level=level, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
        return LogLines()
    console = Console()
    logging.basicConfig(level=level, handlers=[ConsoleLog(console)])
    return LiveTable(console)


def _lcm_url(config: BridgeConfig) -> str:
    """Where the demo publishes: the config's LCM bus."""
    return str(getattr(config.settings("lcm"), "url", DEFAULT_URL))
