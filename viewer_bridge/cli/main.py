"""The `viewer-bridge` command line."""

from __future__ import annotations

import argparse
import functools
import importlib.metadata
import itertools
import logging
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np
import yaml
from rich.console import Console

from viewer_bridge.cli import bag_convert, lcm_types
from viewer_bridge.cli.arguments import (
    IMAGE_SUFFIXES,
    Parser,
    byte_count,
    camera,
    fail,
    field_of_view,
    image_size,
    input_file,
    lcm_source,
    output_file,
    port,
    positive,
    regex,
    split_ros_args,
    worker_count,
)
from viewer_bridge.cli.dump import as_json, as_text
from viewer_bridge.config.bridge import BUILTIN_CONFIGS, BridgeConfig, load_config
from viewer_bridge.config.commands import COMMAND_FLAG
from viewer_bridge.config.mappings import format_names, reference_markdown
from viewer_bridge.errors import BridgeError, ConfigError, Interrupted, SceneError, UsageError
from viewer_bridge.examples import EXAMPLES, drake_missing, run_example
from viewer_bridge.examples.demo import run_demo
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.model.skipped import collecting
from viewer_bridge.router import Router
from viewer_bridge.router.status import ConsoleLog, LiveTable, LogLines, StatusView, counted
from viewer_bridge.router.workers import Workers
from viewer_bridge.transports.lcm import DEFAULT_URL, LcmEvent, Subscription, read_log
from viewer_bridge.transports.lcm_url import log_to_write
from viewer_bridge.transports.origins import ANY_ORIGIN, is_origin_pattern
from viewer_bridge.transports.ros_names import ros_argument_problem


def _lcm_types_option(command: argparse.ArgumentParser) -> None:
    command.add_argument(
        "--lcm-types",
        action="append",
        default=[],
        metavar="PATH_OR_MODULE",
        help="LCM types to know besides the project's and Drake's: a .lcm file, a folder of them "
        "(searched recursively) or an lcm-gen'd Python module by import name (repeatable)",
    )


def _parser() -> argparse.ArgumentParser:
    # --debug before or after the command: `viewer-bridge --debug run` or `viewer-bridge run --debug`.
    debug = Parser(add_help=False)
    debug.add_argument(
        "--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of an internal error"
    )
    parser = Parser(
        prog="viewer-bridge",
        description="Translate Drake's LCM messages (its viewer scene, and any LCM type) between ecosystems.",
        parents=[debug],
    )
    parser.set_defaults(debug=False)
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    commands = parser.add_subparsers(dest="command", required=True)
    add = functools.partial(commands.add_parser, parents=[debug])

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
    _lcm_types_option(dump)
    dump.add_argument("--duration", type=positive, help="with --live: stop after this many seconds")
    dump.add_argument(
        "--demo", action="store_true", help="with --live: also publish the demo scene on the same URL"
    )

    demo = add("demo", help="publish a moving Drake-like scene with every shape over LCM")
    demo.add_argument("--url", type=lcm_source, default=DEFAULT_URL, help="LCM URL to publish on")
    demo.add_argument(
        "--duration", type=positive, help="stop after this many seconds (default: until Ctrl-C)"
    )
    demo.add_argument("--rate", type=positive, default=60.0, help="draw messages per second")

    example = add(
        "example",
        help="run an example pydrake simulation that publishes over LCM (needs Drake: "
        "pip install 'viewer-bridge[drake]')",
        description="Example simulations: " + "; ".join(f"{name}: {what}" for name, what in EXAMPLES.items()),
    )
    example.add_argument("name", choices=list(EXAMPLES), help="which example")
    example.add_argument("--duration", type=positive, default=10.0, metavar="S", help="seconds to simulate, in real time")
    example.add_argument(
        "--lcm-url",
        type=lcm_source,
        default=DEFAULT_URL,
        metavar="URL",
        help="LCM URL to publish on (file://LOG?mode=w records a log)",
    )

    add(
        "mappings", help="print the mapping reference (mappings/REFERENCE.md) from the tables"
    )

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
        help="override a transport setting, e.g. foxglove.port=9000 or ros.namespace=/sim1, or the "
        "commands section's, e.g. commands.max_age_ms=500 (repeatable)",
    )
    _lcm_types_option(run)
    run.add_argument(
        COMMAND_FLAG,
        action="append",
        default=[],
        type=regex,
        metavar="REGEX",
        help="LCM channels (a regular expression matched against the whole name) that ROS 2 and Foxglove "
        "may command by publishing on /lcm_in/<channel> (repeatable; default: none, nothing is written)",
    )
    run.add_argument(
        "--stats-json",
        type=output_file(),
        metavar="PATH",
        help="write per-route stats as JSON every period and at exit",
    )
    run.add_argument(
        "--stats-period", type=positive, default=5.0, metavar="S", help="seconds between stats lines"
    )
    run.add_argument(
        "--duration", type=positive, metavar="S", help="stop after S seconds (default: until Ctrl-C)"
    )
    run.add_argument("--demo", action="store_true", help="also publish the demo scene on the LCM URL")
    run.add_argument(
        "--workers",
        type=worker_count,
        metavar="N",
        help="run the routes on N worker processes, placed by their source (default: the config's "
        "workers, 1: all in this process); a route's worker: K pins it; Ctrl-C exits 130",
    )
    run.add_argument(
        "-q", "--quiet", action="store_true", help="print only warnings and errors (no route table or lines)"
    )

    serve = add("serve-render", help="serve Drake's glTF render API (RenderEngineGltfClient)")
    serve.add_argument("--host", default="127.0.0.1", help="address to listen on (127.0.0.1: this host only)")
    serve.add_argument("--port", type=port, default=8000, help="TCP port to listen on (0: any free port)")
    serve.add_argument(
        "--max-upload",
        type=byte_count,
        default=256 * 1024 * 1024,
        metavar="BYTES",
        help="largest request body accepted",
    )
    serve.add_argument(
        "--allow-origin",
        action="append",
        type=_origin,
        default=[],
        metavar="ORIGIN",
        help="also accept posts from browser pages of this origin (scheme://host[:port], * for any run of "
        "characters but /; '*': any page); loopback pages and clients that send no Origin always may; repeatable",
    )

    shot = add(
        "snapshot", help="render the current scene of a log or a live LCM bus to a PNG or JPEG"
    )
    shot.add_argument("source", type=lcm_source, help="an .lcmlog file, or an LCM URL to listen on")
    shot.add_argument(
        "out", type=output_file(IMAGE_SUFFIXES), help="the image to write: .png, or .jpg/.jpeg for JPEG"
    )
    shot.add_argument("--role", default="", help="channel suffix, e.g. ILLUSTRATION (default: unsuffixed)")
    shot.add_argument("--image", choices=["color", "label", "depth"], default="color")
    shot.add_argument("--size", type=image_size, default="640x480", help="WIDTHxHEIGHT")
    shot.add_argument("--fov", type=field_of_view, default=45.0, help="vertical field of view, degrees")
    shot.add_argument(
        "--camera",
        type=camera,
        metavar="EX,EY,EZ,TX,TY,TZ",
        help="eye and target (default: frame the scene)",
    )
    shot.add_argument("--duration", type=positive, default=3.0, help="with an LCM URL: seconds to listen")
    shot.add_argument("--contacts", action="store_true", help="draw the last CONTACT_RESULTS over the scene")
    shot.add_argument(
        "--hide",
        type=regex,
        metavar="REGEX",
        help="leave out links whose names match (e.g. a body over a contact)",
    )

    convert = add(
        "convert", help="translate an LCM log into an MCAP file (ROS 2 or Foxglove) or a Rerun .rrd file"
    )
    convert.add_argument("log", type=bag_convert.input_path, help="an .lcmlog file, or a ROS 2 bag (MCAP, rosbag2 folder)")
    convert.add_argument(
        "mcap", type=output_file(), help="the .mcap (or Rerun .rrd) file to write (written as NAME.partial until complete)"
    )
    convert.add_argument("-c", "--config", help="a YAML config whose LCM routes are used (default: built-in)")
    convert.add_argument(
        "--schema",
        choices=["ros2", "foxglove"],
        default="ros2",
        help="ros2: CDR with ros2msg schemas; foxglove: Foxglove's protobuf SceneUpdate and FrameTransforms "
        "(in both, channels of any known LCM type as /lcm/<channel>, ros2msg and CDR)",
    )
    convert.add_argument(
        "--format",
        choices=["mcap", "rrd"],
        help="the file to write, for an output named other than .mcap or .rrd (default: its extension says)",
    )
    convert.add_argument("--force", action="store_true", help="replace the output file if it exists")
    _lcm_types_option(convert)
    convert.add_argument(
        "--lcm-channels",
        type=regex,
        metavar="REGEX",
        help="the channels written as /lcm/<channel> in their own type (any known LCM type); default: all",
    )
    convert.add_argument("--topics", type=regex, metavar="REGEX", help="a ROS 2 bag in: the topics to convert (default all)")
    convert.add_argument("--lcm-types-out", type=Path, metavar="DIR", help="a ROS 2 bag in: write the .lcm files here")

    interfaces = add(
        "ros-interfaces",
        help="build ROS 2 interface packages PyPI has no wheel for (tf2_msgs, LCM types) into the venv, "
        "or write the LCM types' packages for a colcon workspace",
    )
    interfaces.add_argument("action", choices=["install", "status", "generate"])
    interfaces.add_argument(
        "names",
        nargs="*",
        metavar="NAME",
        help="optional: the packages to install or show, or to generate with those they nest (default: all of them)",
    )
    interfaces.add_argument(
        "--lcm-types",
        action="append",
        default=[],
        metavar="SRC",
        help="LCM types (.lcm files, folders, lcm-gen'd modules): install builds their *_lcm_msgs packages "
        "instead of tf2_msgs; generate writes them beside the project's and Drake's (repeatable)",
    )
    interfaces.add_argument(
        "-o", "--output", type=Path, metavar="DIR", help="generate: the folder to write the packages to (a workspace's src/)"
    )
    lcm_types.add_command(add)
    return parser


def _version() -> str:
    try:
        return importlib.metadata.version("viewer-bridge")
    except importlib.metadata.PackageNotFoundError:  # run from a checkout that is not installed
        return "(not installed)"


def _dump(args: argparse.Namespace) -> int:
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


def _demo(args: argparse.Namespace) -> int:
    stop = threading.Event()  # Ctrl-C or SIGTERM: the summary line, then exit 0
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda *_: stop.set())
    until = f"for {args.duration:g} s" if args.duration else "until Ctrl-C"
    print(f"publishing the demo scene on {args.url} at {args.rate:g} Hz, {until}", flush=True)
    sent = run_demo(args.url, args.duration, args.rate, stop=stop)
    print(f"published {sent} draw messages on {args.url}")
    return 0


def _example(args: argparse.Namespace) -> int:
    if missing := drake_missing():
        raise UsageError(missing)
    print(f"example {args.name}: publishing on {args.lcm_url} for {args.duration:g} s", flush=True)
    run_example(args.name, args.lcm_url, args.duration)
    print(f"example {args.name}: done")
    return 0


def _mappings(args: argparse.Namespace) -> int:
    print(reference_markdown(format_names()), end="")
    return 0


def _run(args: argparse.Namespace) -> int:
    if args.print_default_config or args.print_config:
        name = args.print_config or "default"
        if name not in BUILTIN_CONFIGS:
            raise UsageError(f"no built-in config {name!r} (known: {', '.join(BUILTIN_CONFIGS)})")
        print(BUILTIN_CONFIGS[name], end="")
        return 0
    view = _status_view(args.quiet)
    try:
        config = _with_lcm_types(load_config(args.config), args.lcm_types).allowing_commands(args.allow_commands)
        if args.lcm_url:
            config = config.with_settings("lcm", url=args.lcm_url)
        for setting in args.set:
            config = _with_setting(config, setting, args.config)
        if args.ros_args:
            _uses(config, "ros", "--ros-args", args.config)
            config = config.with_settings("ros", ros_args=args.ros_args)
        if args.demo and log_to_write(_lcm_url(config)):
            raise UsageError(
                f"--demo: the routes would read the demo on {_lcm_url(config)}, a log LCM only writes; "
                "record the demo itself with `viewer-bridge demo --url URL`"
            )
        workers = args.workers or config.workers
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
    return 130 if isinstance(router, Workers) and signal.SIGINT in signals else 0


def _with_lcm_types(config: BridgeConfig, sources: list[str]) -> BridgeConfig:
    """The config with `--lcm-types` added to its `lcm_types`."""
    return config.model_copy(update={"lcm_types": [*config.lcm_types, *sources]}) if sources else config


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
    section of the config's own (`commands.max_age_ms=500`) is set the same way."""
    name, equals, value = setting.partition("=")
    transport, _, key = name.partition(".")
    if not (transport and key and equals):
        raise UsageError(f"--set {setting!r}: expected TRANSPORT.KEY=VALUE, e.g. foxglove.port=9000")
    if transport not in BridgeConfig.model_fields:
        _uses(config, transport, f"--set {setting}", config_name)
    try:
        return config.with_settings(transport, **{key: yaml.safe_load(value)})
    except ConfigError as error:
        raise UsageError(f"--set {setting}: {error.key}: {error.reason}") from None


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


def _convert(args: argparse.Namespace) -> int:
    if bag_convert.wanted(args):  # a ROS 2 bag into an LCM log
        return bag_convert.run(args)
    from viewer_bridge.cli.log_convert import checked_output, convert  # MCAP: the foxglove extra; .rrd: rerun

    logging.basicConfig(level=logging.INFO, format="%(message)s")
    written_as = checked_output(Path(args.log), Path(args.mcap), args.force, args.format)  # refused before any work
    # An .rrd file is a Rerun recording: builtin:rerun's routes unless a config is given.
    config = _with_lcm_types(load_config(args.config or ("builtin:rerun" if written_as == "rrd" else None)), args.lcm_types)
    # Ctrl-C (or a SIGTERM) stops after the message being converted: the MCAP is closed properly.
    stop = threading.Event()
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda *_: stop.set())
    try:
        done = convert(
            args.log,
            args.mcap,
            config,
            progress=sys.stderr.isatty(),
            schema=args.schema,
            force=args.force,
            config_name=args.config or "the built-in config",
            stop=stop,
            lcm_channels=args.lcm_channels,
            output=written_as,
        )
    except Interrupted as interrupted:
        print(f"viewer-bridge convert: {interrupted}", file=sys.stderr)
        return 130
    for line in done.skipped_lines():
        print(f"viewer-bridge convert: {line}", file=sys.stderr)
    for topic, count in sorted(done.messages.items()):
        print(f"{count:8d}  {topic}")
    if done.written:
        print(done.summary())
    problem = done.problem()  # asked for and not done: exit 1, not a mistake in the arguments (2)
    return 0 if problem is None else fail("convert", problem, status=1)


def _snapshot(args: argparse.Namespace) -> int:
    from viewer_bridge.render.snapshot import (  # OpenGL only for this command
        events_from,
        latest_contacts,
        latest_scene,
        snapshot,
        with_contacts,
        without_links,
    )

    width, height = args.size
    eye = target = None
    if args.camera:
        eye, target = np.array(args.camera[:3]), np.array(args.camera[3:])
    jpeg = Path(args.out).suffix.lower() != ".png"
    if jpeg and args.image == "depth":
        raise UsageError("a depth image is 16-bit: write it as .png (JPEG holds 8 bits)")
    events = events_from(args.source, args.duration)
    scene = latest_scene(events, args.role.upper())
    if args.hide:
        scene = without_links(scene, args.hide)
    if args.contacts:
        results = latest_contacts(events)
        if results is None:
            raise SceneError(
                "no CONTACT_RESULTS message in the source: Drake publishes them when a simulation calls "
                "ConnectContactResultsToDrakeVisualizer (`viewer-bridge example contacts` does)"
            )
        scene = with_contacts(scene, results)
    with collecting() as skipped:  # a geometry that cannot be drawn is left out, and named
        picture = snapshot(scene, width, height, args.fov, eye, target, args.image, "JPEG" if jpeg else "PNG")
    for geometry in skipped:
        print(f"viewer-bridge snapshot: warning: {geometry}", file=sys.stderr)
    Path(args.out).write_bytes(picture)
    drawn = scene.geometry_count() - len(skipped)
    print(f"wrote {args.out}: {counted(len(scene.links), 'link')}, {counted(drawn, 'geometry', 'geometries')} "
          f"({len(skipped)} skipped)")
    return 0


def _origin(text: str) -> str:
    """An --allow-origin value: an origin or a pattern of origins (no path: browsers send none)."""
    if not is_origin_pattern(text):
        raise argparse.ArgumentTypeError(f"{text!r} is no origin: write scheme://host[:port] (no path), "
                                         "with * for any run of characters but '/', or '*' alone")  # fmt: skip
    return text


def _serve_render(args: argparse.Namespace) -> int:
    from viewer_bridge.render.server import make_server  # OpenGL only for this command

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
    try:
        server = make_server(args.host, args.port, args.max_upload, args.allow_origin)
    except OSError as error:  # e.g. the port is taken, or the host is not an address of this machine
        raise UsageError(f"cannot listen on {args.host}:{args.port}: {error.strerror or error}") from None
    # Ctrl-C stops it cleanly from the moment it says it is ready.
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda *_: threading.Thread(target=server.shutdown).start())
    # Drake's client takes the base URL and adds the endpoint (/render) itself: print that one.
    host, port_number = server.server_address[:2]
    host = host.decode() if isinstance(host, bytes) else host
    base_url = f"http://{host}:{port_number}"
    logging.getLogger("viewer_bridge").info(
        'render server on %s (Drake: RenderEngineGltfClientParams(base_url="%s"), which posts to /render)%s',
        base_url,
        base_url,
        "; origin check off: any web page may post" if ANY_ORIGIN in args.allow_origin else "",
    )
    server.serve_forever()
    server.server_close()
    return 0


def _ros_interfaces(args: argparse.Namespace) -> int:
    from viewer_bridge.ros_build import interfaces as ros_interfaces

    say = lambda line: print(line, file=sys.stderr)  # noqa: E731
    if args.action == "generate":  # the LCM types' packages: the project's and Drake's, and --lcm-types'
        if args.output is None:
            raise UsageError("generate needs -o DIR")
        documented = _lcm_ros_definitions(args.lcm_types, comments=True, warn=say)
        for folder in ros_interfaces.generate_packages(documented, args.output, only=args.names or None):
            print(folder)
        return 0
    if args.lcm_types:
        definitions = _lcm_ros_definitions(args.lcm_types)
        if args.action == "install":
            ros_interfaces.build(definitions, log=say, only=args.names or None)
        else:
            chosen = ros_interfaces.packages(definitions)
            digests = ros_interfaces.digests(chosen)
            for package in chosen:
                built = ros_interfaces.current(package, digests[package.name])
                print(f"{package.name}: {'installed' if built else 'missing or outdated'} in {sys.prefix}")
        return 0
    unknown = [name for name in args.names if name not in ros_interfaces.INTERFACES]
    if unknown:
        known = ", ".join(ros_interfaces.INTERFACES)
        raise UsageError(f"unknown interface package {', '.join(unknown)} (known: {known})")
    if args.action == "status":
        absent = ros_interfaces.missing()
        for name in args.names or ros_interfaces.INTERFACES:
            print(f"{name}: {'missing' if name in absent else 'installed'} in {sys.prefix}")
        return 0
    ros_interfaces.install(args.names or None, log=say)
    return 0


def _lcm_ros_definitions(
    sources: Sequence[str], *, comments: bool = False, warn: Callable[[str], None] | None = None
) -> dict[str, str]:
    """The ROS 2 `.msg` definitions of the LCM types of `sources` (and the project's own), with
    the `.lcm` files' comments when `comments` (for a workspace's files); `warn` hears each type
    left out (no ROS 2 form) and the library's other warnings."""
    from viewer_bridge.lcmcodec.library import TypeLibrary  # rosbags: only for this command

    library = TypeLibrary.load(sources)
    if warn is not None:
        for warning in library.warnings:
            warn(f"viewer-bridge ros-interfaces: {warning}")
    return dict(library.ros_definitions(comments=comments))


_HANDLERS = {
    "dump": _dump,
    "demo": _demo,
    "example": _example,
    "mappings": _mappings,
    "run": _run,
    "convert": _convert,
    "serve-render": _serve_render,
    "snapshot": _snapshot,
    "ros-interfaces": _ros_interfaces,
    "lcm-types": lcm_types.run,
}


def main(argv: Sequence[str] | None = None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    try:
        words, ros_args = split_ros_args(words)  # everything in --ros-args ... [--] is rclpy's
    except UsageError as error:
        command = next((word for word in words if word in _HANDLERS), "")
        parser.exit(2, f"{' '.join(filter(None, ('viewer-bridge', command)))}: {error}\n")
    if not words:  # no command: what there is to run
        parser.print_help()
        return 2
    args = parser.parse_args(words)
    args.ros_args = ros_args
    if ros_args and args.command != "run":
        parser.exit(2, f"viewer-bridge {args.command}: --ros-args: only `run` is a ROS 2 node\n")
    for flag, value in itertools.pairwise(ros_args):  # each flag and its value, as rcl checks them
        if problem := ros_argument_problem(flag, value):
            parser.exit(2, f"viewer-bridge run: --ros-args: {flag} {value}: {problem}\n")
    try:
        return _HANDLERS[args.command](args)
    except BridgeError as error:  # a mistake in what was given, or what this machine lacks: one line
        return fail(args.command, str(error))
    except KeyboardInterrupt:  # Ctrl-C before a command's own handling of it: no traceback
        return 130
    except Exception as error:  # a bug: said as one, with its traceback under --debug
        if args.debug:
            raise
        print(
            f"viewer-bridge {args.command}: internal error: {type(error).__name__}: {error} "
            "(a bug in viewer-bridge: --debug shows its traceback)",
            file=sys.stderr,
        )
        return 1


if __name__ == "__main__":
    sys.exit(main())
