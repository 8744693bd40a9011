"""`viewer-bridge convert`: an LCM log into MCAP or a Rerun .rrd (`cli/log_convert.py`), or a ROS 2
bag into an LCM log (`cli/bag_convert.py`); the input says which."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from pathlib import Path

from viewer_bridge.cli import bag_convert
from viewer_bridge.cli.arguments import AddCommand, fail, lcm_types_option, output_file, regex
from viewer_bridge.config.options import RunOptions, config_of
from viewer_bridge.errors import Interrupted


def add_command(add: AddCommand) -> None:
    """The `convert` command's arguments (both directions'), on the parser `add` makes."""
    convert = add(
        "convert", help="translate an LCM log into an MCAP file (ROS 2 or Foxglove) or a Rerun .rrd file"
    )
    convert.add_argument(
        "log", type=bag_convert.input_path, help="an .lcmlog file, or a ROS 2 bag (MCAP, rosbag2 folder)"
    )
    convert.add_argument(
        "mcap",
        type=output_file(),
        help="the .mcap (or Rerun .rrd) file to write (written as NAME.partial until complete)",
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
    lcm_types_option(convert)
    convert.add_argument(
        "--lcm-channels",
        type=regex,
        metavar="REGEX",
        help="the channels written as /lcm/<channel> in their own type (any known LCM type); default: all",
    )
    convert.add_argument(
        "--topics", type=regex, metavar="REGEX", help="a ROS 2 bag in: the topics to convert (default all)"
    )
    convert.add_argument(
        "--lcm-types-out", type=Path, metavar="DIR", help="a ROS 2 bag in: write the .lcm files here"
    )


def run(args: argparse.Namespace) -> int:
    """Convert; print messages per topic, what was skipped, and what was written (exit 1 when
    something asked for was not done; 130 when Ctrl-C stopped it, saying what it kept)."""
    # Ctrl-C (or a SIGTERM) stops after the message being converted: the output is closed properly
    # and kept as NAME.partial (viewer_bridge/util/partial.py), in either direction.
    stop = threading.Event()
    for signal_number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signal_number, lambda *_: stop.set())
    try:
        if bag_convert.wanted(args):  # a ROS 2 bag into an LCM log
            return bag_convert.run(args, stop)
        return _from_lcm_log(args, stop)
    except Interrupted as interrupted:
        print(f"viewer-bridge convert: {interrupted}", file=sys.stderr)
        return 130


def _from_lcm_log(args: argparse.Namespace, stop: threading.Event) -> int:
    from viewer_bridge.cli.log_convert import checked_output, convert  # MCAP: the foxglove extra; .rrd: rerun

    logging.basicConfig(level=logging.INFO, format="%(message)s")
    # refused before any work
    written_as = checked_output(Path(args.log), Path(args.mcap), args.force, args.format)
    # An .rrd file is a Rerun recording: builtin:rerun's routes unless a config is given.
    named = args.config or ("builtin:rerun" if written_as == "rrd" else None)
    config = config_of(RunOptions(config=named, lcm_types=args.lcm_types))
    done = convert(
        args.log,
        args.mcap,
        config,
        progress=True,  # a bar on a terminal, a line per tenth on a pipe (when it takes seconds)
        schema=args.schema,
        force=args.force,
        config_name=args.config or "the built-in config",
        stop=stop,
        lcm_channels=args.lcm_channels,
        output=written_as,
    )
    for line in done.skipped_lines():
        print(f"viewer-bridge convert: {line}", file=sys.stderr)
    for topic, count in sorted(done.messages.items()):
        print(f"{count:8d}  {topic}")
    if done.written:
        print(done.summary())
    problem = done.problem()  # asked for and not done: exit 1, not a mistake in the arguments (2)
    return 0 if problem is None else fail("convert", problem, status=1)
