"""The `viewer-bridge` command line: the top-level parser and the dispatch to the command modules,
each of which owns its sub-command's arguments (`add_command`) and its work (`run`)."""

from __future__ import annotations

import argparse
import importlib.metadata
import itertools
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from viewer_bridge.cli import (
    convert,
    demo,
    dump_command,
    example,
    layout,
    lcm_types,
    mappings,
    play,
    ros_interfaces,
    run,
    serve_render,
    snapshot,
)
from viewer_bridge.cli.arguments import AddCommand, Parser, fail, split_ros_args
from viewer_bridge.errors import BridgeError, UsageError
from viewer_bridge.transports.ros_names import ros_argument_problem
from viewer_bridge.util.hints import DEBUG_ENV


class Command(Protocol):
    """A command module: its sub-command's arguments, and what it does with them (an exit status)."""

    def add_command(self, add: AddCommand) -> None: ...

    def run(self, args: argparse.Namespace) -> int: ...


# In the order `viewer-bridge --help` lists them.
COMMANDS: tuple[Command, ...] = (
    dump_command,
    demo,
    example,
    mappings,
    run,
    play,
    layout,
    serve_render,
    snapshot,
    convert,
    ros_interfaces,
    lcm_types,
)


def _parser() -> tuple[argparse.ArgumentParser, frozenset[str]]:
    """The parser, and the names of its commands."""
    # --debug before or after the command: `viewer-bridge --debug run` or `viewer-bridge run --debug`.
    debug = Parser(add_help=False)
    debug.add_argument(
        "--debug",
        action="store_true",
        default=argparse.SUPPRESS,
        help="show the traceback of an internal error",
    )
    parser = Parser(
        prog="viewer-bridge",
        description="Translate Drake's LCM messages (its viewer scene, and any LCM type) between ecosystems.",
        parents=[debug],
    )
    parser.set_defaults(debug=False)
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    commands = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_command(_adding(commands, debug, command.run))
    return parser, frozenset(commands.choices or ())


def _adding(
    commands: argparse._SubParsersAction[Any],
    debug: argparse.ArgumentParser,
    handler: Callable[[argparse.Namespace], int],
) -> AddCommand:
    """`add_parser` for one command module: each sub-command takes --debug and, once parsed,
    names the module's `run` as `args.handler`."""

    def add(name: str, **options: Any) -> argparse.ArgumentParser:
        command: argparse.ArgumentParser = commands.add_parser(name, parents=[debug], **options)
        command.set_defaults(handler=handler)
        return command

    return add


def _version() -> str:
    try:
        return importlib.metadata.version("viewer-bridge")
    except importlib.metadata.PackageNotFoundError:  # run from a checkout that is not installed
        return "(not installed)"


def main(argv: Sequence[str] | None = None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)
    parser, names = _parser()
    try:
        words, ros_args = split_ros_args(words)  # everything in --ros-args ... [--] is rclpy's
    except UsageError as error:
        command = next((word for word in words if word in names), "")
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
    handler: Callable[[argparse.Namespace], int] = args.handler
    if args.debug:  # every once-per-machine hint said again, in worker processes too
        os.environ[DEBUG_ENV] = "1"
    try:
        return handler(args)
    except BridgeError as error:  # a mistake in what was given, or what this machine lacks: one line
        return fail(args.command, str(error))
    except KeyboardInterrupt:  # Ctrl-C before a command's own handling of it: one line, no traceback
        print(f"viewer-bridge {args.command}: interrupted", file=sys.stderr)
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
