"""The command line's checks: every argument is checked before a command does any work.

Each check is an argparse `type=` function: a mistake becomes `ArgumentTypeError`, which
`Parser.error` prints as one line, `viewer-bridge <cmd>: argument --x: <what was wrong>`, with
exit status 2 and no traceback. `split_ros_args` separates the ROS 2 arguments (`--ros-args ...`,
ended by `--` or by the end of the line, as for any ROS 2 node) from the command's own.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

from viewer_bridge.errors import UsageError
from viewer_bridge.transports.command_policy import channel_pattern_problem, topic_pattern_problem
from viewer_bridge.transports.lcm_url import log_to_write


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Help texts that show each option's default, when it has one worth showing."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        # Nothing worth showing, or the help says the default in its own words ("default: unsuffixed").
        if action.default in (None, False, [], "", argparse.SUPPRESS) or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


class Parser(argparse.ArgumentParser):
    """argparse, with mistakes as one line `viewer-bridge <cmd>: ...` (exit 2) and defaults in help."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def fail(command: str, message: str, status: int = 2) -> int:
    """Report a mistake found after parsing as argparse reports its own; the exit status (2: a
    mistake in what was given; 1: a command that ran and could not do what was asked)."""
    print(f"viewer-bridge {command}: {message}", file=sys.stderr)
    return status


def regex(text: str) -> str:
    """A regular expression (kept as text; it compiles)."""
    try:
        re.compile(text)
    except re.error as error:
        raise argparse.ArgumentTypeError(f"{text!r} is not a regular expression: {error}") from None
    return text


def topic_regex(text: str) -> str:
    """A regular expression that can match a ROS 2 topic (none of its alternatives lacks the leading /)."""
    if (problem := topic_pattern_problem(regex(text))) is not None:
        raise argparse.ArgumentTypeError(problem)
    return text


def channel_regex(text: str) -> str:
    """A regular expression that can match an LCM channel a command reaches (none begins with /)."""
    if (problem := channel_pattern_problem(regex(text))) is not None:
        raise argparse.ArgumentTypeError(problem)
    return text


def positive(text: str) -> float:
    """A finite number greater than 0."""
    value = _number(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be greater than 0, got {text}")
    return value


def non_negative(text: str) -> float:
    """A finite number of 0 or more."""
    value = _number(text)
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text}")
    return value


def field_of_view(text: str) -> float:
    """A vertical field of view in degrees: more than 0, less than 180."""
    value = _number(text)
    if not 0 < value < 180:
        raise argparse.ArgumentTypeError(f"must be between 0 and 180 degrees (both excluded), got {text}")
    return value


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def port(text: str) -> int:
    """A TCP port: 0 (any free port) to 65535."""
    return _whole(text, "a port number", 0, 65535, "a port is 0 (any free one) to 65535")


def byte_count(text: str) -> int:
    """A size in bytes, at least 1."""
    return _whole(text, "a whole number of bytes", 1, None, "must be at least 1 byte")


def worker_count(text: str) -> int:
    """A number of worker processes: 1 to 256."""
    return _whole(text, "a number of workers", 1, 256, "workers are 1 to 256")


# --workers auto: the bridge counts the free cores (`viewer_bridge.router.workers.auto_workers`).
AUTO = "auto"


def worker_count_or_auto(text: str) -> int | str:
    """A number of worker processes (1 to 256), or `auto`."""
    return AUTO if text.strip().lower() == AUTO else worker_count(text)


def _whole(text: str, what: str, low: int, high: int | None, rule: str) -> int:
    """`text` as a whole number from `low` to `high` (None: no limit); `rule` says the range."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
    if value < low or (high is not None and value > high):
        raise argparse.ArgumentTypeError(f"{rule}, got {text}")
    return value


MAX_IMAGE_SIDE = 16384  # what OpenGL drivers commonly allow for a framebuffer


def image_size(text: str) -> tuple[int, int]:
    """`WIDTHxHEIGHT` in pixels, each 1 to `MAX_IMAGE_SIDE`."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if match is None:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT, e.g. 640x480")
    width, height = int(match.group(1)), int(match.group(2))
    if not (1 <= width <= MAX_IMAGE_SIDE and 1 <= height <= MAX_IMAGE_SIDE):
        raise argparse.ArgumentTypeError(f"width and height must be 1 to {MAX_IMAGE_SIDE} pixels, got {text}")
    return width, height


def camera(text: str) -> tuple[float, ...]:
    """`EX,EY,EZ,TX,TY,TZ`: where the camera is and what it looks at, two different points."""
    values = tuple(_number(part) for part in text.split(","))
    if len(values) != 6:
        raise argparse.ArgumentTypeError(f"needs six numbers, eye x,y,z and target x,y,z; got {len(values)}")
    if values[:3] == values[3:]:
        raise argparse.ArgumentTypeError("the eye and the target are the same point")
    return values


IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def input_file(text: str) -> str:
    """A file that exists and can be read."""
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder, not a file")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text}: no such file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text}: not readable")
    return text


_LCM_PROVIDERS = ("udpm", "udp", "mpudpm", "memq", "tcpq", "file")


def lcm_source(text: str) -> str:
    """An LCM URL (`udpm://...`, `file://LOG?speed=S`, `file://LOG?mode=w` to write one, ...) or the
    path of a log file."""
    if "://" not in text:
        return input_file(text)
    provider, _, rest = text.partition("://")
    if provider not in _LCM_PROVIDERS:
        raise argparse.ArgumentTypeError(
            f"{text}: unknown LCM provider {provider!r} (known: {', '.join(_LCM_PROVIDERS)}; or a log file)"
        )
    if provider == "file":
        if log_to_write(text) is not None:  # LCM writes a log there (`?mode=w`): its folder must exist
            output_file()(rest.partition("?")[0])
        else:
            input_file(rest.partition("?")[0])
    return text


def output_file(suffixes: Sequence[str] = ()) -> Callable[[str], str]:
    """A file to write: its folder exists; with `suffixes`, its name ends in one of them."""

    def check(text: str) -> str:
        path = Path(text)
        if suffixes and path.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(f"{text}: the name must end in {', '.join(suffixes)}")
        folder = path.parent
        if not folder.is_dir():
            raise argparse.ArgumentTypeError(f"{text}: the folder {folder} does not exist")
        if path.is_dir():
            raise argparse.ArgumentTypeError(f"{text} is a folder, not a file")
        return text

    check.__name__ = "output file"  # what argparse names in its own messages
    return check


# rcl's flags after --ros-args (rcl/arguments.h): the ones that take a value, and the switches.
_ROS_FLAGS_WITH_VALUE = frozenset(
    {"-r", "--remap", "-p", "--param", "--params-file", "-e", "--enclave", "--log-level",
     "--log-config-file", "--log-file-name"}
)  # fmt: skip
_ROS_SWITCHES = frozenset(
    f"--{state}-{what}"
    for state in ("enable", "disable")
    for what in ("stdout-logs", "rosout-logs", "external-lib-logs")
)


# What a command module's `add_command` is given: `add_parser` of the sub-commands, with the
# options every command shares (--debug) already in.
AddCommand = Callable[..., argparse.ArgumentParser]


def lcm_types_option(command: argparse.ArgumentParser) -> None:
    """`--lcm-types`, as the commands that decode LCM messages take it."""
    command.add_argument(
        "--lcm-types",
        action="append",
        default=[],
        metavar="PATH_OR_MODULE",
        help="LCM types to know besides the project's and Drake's: a .lcm file, a folder of them "
        "(searched recursively) or an lcm-gen'd Python module by import name (repeatable)",
    )


def split_ros_args(words: Sequence[str]) -> tuple[list[str], list[str]]:
    """(the command's own words, the ROS arguments): each `--ros-args` section runs to `--` or the end.

    Raises `UsageError` for a word in a section that is not a ROS argument (the command's own
    options belong before `--ros-args` or after `--`).
    """
    own: list[str] = []
    ros: list[str] = []
    index = 0
    while index < len(words):
        if words[index] != "--ros-args":
            own.append(words[index])
            index += 1
            continue
        index += 1
        while index < len(words) and words[index] != "--":
            word = words[index]
            if word in _ROS_FLAGS_WITH_VALUE:
                if index + 1 >= len(words) or words[index + 1] == "--":
                    raise UsageError(f"--ros-args: {word} needs a value")
                ros += [word, words[index + 1]]
                index += 2
            elif word in _ROS_SWITCHES:
                ros.append(word)
                index += 1
            else:
                raise UsageError(
                    f"--ros-args: {word!r} is not a ROS argument; ROS arguments end at -- "
                    f"(e.g. run --ros-args -r __ns:=/sim1 -- --duration 2)"
                )
        index += 1  # past the `--`
    return own, ros
