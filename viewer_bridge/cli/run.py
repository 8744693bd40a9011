"""`viewer-bridge run`: the router, from a config and the command line's overrides of it."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading

import yaml
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
from viewer_bridge.config.bridge import BUILTIN_CONFIGS, BridgeConfig, load_config
from viewer_bridge.errors import ConfigError, UsageError
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
    view = _status_view(args.quiet)
    try:
        named, without = _builtin_for_this_install() if args.config is None else (args.config, [])
        config = (
            load_config(named, without=without)
            .with_lcm_types(args.lcm_types)
            .allowing_commands(args.allow_commands)
            .with_ros_topics(args.ros_topics)
        )
        if args.lcm_url:
            config = config.with_settings("lcm", url=args.lcm_url)
        for setting in args.set:
            config = _with_setting(config, setting, named)
        if args.ros_args:
            _uses(config, "ros", "--ros-args", named)
            config = config.with_settings("ros", ros_args=args.ros_args)
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


# The transports' names in the line that says which routes were left out.
_SAID = {"ros": "ROS 2", "foxglove": "Foxglove", "zenoh": "Zenoh", "rerun": "Rerun", "ign": "ign-transport"}
# The built-in configs tried, in order, when the default one has no route this install can run.
_FALLBACKS = ("foxglove", "zenoh", "rerun", "ign")


def _builtin_for_this_install() -> tuple[str | None, list[str]]:
    """The built-in config to run when none is named (`-c`), and the transports to leave out of it.

    One rule for every extra: the default config's routes on a transport whose extra is not
    installed are left out, said in one line naming them and the extra that adds them. When none is
    left (`[zenoh]` alone, say), the first built-in config whose every transport is installed runs
    instead, said in one line; with none (the core alone), a `MissingExtra` names the extras. A
    config the user names runs as written, or stops naming what it lacks."""
    from viewer_bridge.config.bridge import routes_on
    from viewer_bridge.util.extras import TRANSPORT_EXTRAS, lacking

    routes = yaml.safe_load(BUILTIN_CONFIGS["default"])["routes"]
    used = dict.fromkeys(
        end["transport"] for route in routes for end in (route["source"], route["destination"])
    )
    absent = {name: module for name in used if (module := lacking(name)) is not None}
    if not absent:
        return None, []
    kept = [route for route in routes if not any(routes_on(route, name) for name in absent)]
    extras = ",".join(dict.fromkeys(TRANSPORT_EXTRAS[name] for name in absent))
    needs = f"{' and '.join(absent.values())}, not installed: pip install 'viewer-bridge[{extras}]'"
    say = logging.getLogger(__name__).warning
    if kept:
        dropped = " and ".join(
            f"{sum(routes_on(route, name) for route in routes)} {_SAID.get(name, name)} routes"
            for name in absent
        )
        say("viewer-bridge: the built-in config's %s left out: they need %s", dropped, needs)
        return None, list(absent)
    for name in _FALLBACKS:
        document = yaml.safe_load(BUILTIN_CONFIGS[name])
        wanted = {
            end["transport"]
            for route in document["routes"]
            for end in (route["source"], route["destination"])
        }
        if all(lacking(transport) is None for transport in wanted):
            say("viewer-bridge: the built-in config's routes need %s; running -c builtin:%s, the built-in "
                "config of what is installed", needs, name)  # fmt: skip
            return f"builtin:{name}", []
    others = [name for name in _FALLBACKS if name != "foxglove"]
    raise UsageError(
        "no built-in config can run: this install has none of their extras: pip install "
        + " or ".join(f"'viewer-bridge[{TRANSPORT_EXTRAS[name]}]'" for name in absent)
        + " for the default config, or "
        + ", ".join(f"[{name}] for -c builtin:{name}" for name in others)
    )


def _status_view(quiet: bool) -> StatusView:
    """A live route table when stdout is a terminal; plain log lines on stderr otherwise."""
    level = logging.WARNING if quiet else logging.INFO
    if quiet or not sys.stdout.isatty():
        logging.basicConfig(level=level, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
        return LogLines()
    console = Console()
    logging.basicConfig(level=level, handlers=[ConsoleLog(console)])
    return LiveTable(console)


def _with_setting(config: BridgeConfig, setting: str, config_name: str | None) -> BridgeConfig:
    """`TRANSPORT.KEY=VALUE` (the value read as YAML: 9000 is a number, true a bool) applied; a
    section of the config's own (`commands.max_age_ms=500`) is set the same way, and a plain
    top-level key of its own (`time=sim`) as `KEY=VALUE`."""
    name, equals, value = setting.partition("=")
    transport, _, key = name.partition(".")
    if equals and not key and name in _TOP_LEVEL_KEYS:
        try:
            return config.with_keys(**{name: yaml.safe_load(value)})
        except ConfigError as error:
            raise UsageError(f"--set {setting}: {error.key}: {error.reason}") from None
    if not (transport and key and equals):
        raise UsageError(
            f"--set {setting!r}: expected TRANSPORT.KEY=VALUE, e.g. foxglove.port=9000, "
            f"or KEY=VALUE for one of {', '.join(_TOP_LEVEL_KEYS)}"
        )
    if transport not in BridgeConfig.model_fields:
        _uses(config, transport, f"--set {setting}", config_name)
    try:
        return config.with_settings(transport, **{key: yaml.safe_load(value)})
    except ConfigError as error:
        raise UsageError(f"--set {setting}: {error.key}: {error.reason}") from None


# The config's own top-level keys that `--set KEY=VALUE` sets (lists and sections have options or dots).
_TOP_LEVEL_KEYS = ("time", "workers", "load_cache", "drake_lcm_types")


def _uses(config: BridgeConfig, transport: str, option: str, config_name: str | None) -> None:
    """Warn about an option for a transport that no route of the config uses: it does nothing.
    (A warning, not a refusal: one command line may serve several configs, e.g. in scripts.)"""
    used = config.transports()
    if transport not in used:
        print(
            f"viewer-bridge run: warning: {option} does nothing: no route of "
            f"{config_name or 'the built-in config'} uses the {transport} transport "
            f"(its routes use: {', '.join(used) or 'none'})",
            file=sys.stderr,
        )


def _lcm_url(config: BridgeConfig) -> str:
    """Where the demo publishes: the config's LCM bus."""
    return str(getattr(config.settings("lcm"), "url", DEFAULT_URL))
