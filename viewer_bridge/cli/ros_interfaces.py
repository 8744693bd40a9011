"""`viewer-bridge ros-interfaces`: ROS 2 interface packages (viewer_bridge/ros_build/) installed
into the venv, shown, or generated for a colcon workspace."""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from viewer_bridge.cli.arguments import AddCommand
from viewer_bridge.errors import UsageError
from viewer_bridge.util.progress import Steps, progress, steps

# What generate says when pydrake is missing: the project ships Drake's viewer and driver types
# (lcmtypes/), the others come with pydrake.
DRAKE_LEFT_OUT = (
    "viewer-bridge ros-interfaces: Drake's other LCM types (lcmt_panda_status, lcmt_scope, lcmt_allegro_command "
    "and the rest) left out: they come with pydrake's drake module, not installed: pip install 'viewer-bridge[drake]'"
)


def add_command(add: AddCommand) -> None:
    """The `ros-interfaces` command's arguments, on the parser `add` makes."""
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
        "-y",
        "--yes",
        action="store_true",
        help="install: pip install the wheels a build needs (rclpy, rosidl's generators: about a hundred "
        "distributions) without asking; without it, install asks when run in a terminal and refuses otherwise",
    )
    interfaces.add_argument(
        "-o",
        "--output",
        type=Path,
        metavar="DIR",
        help="generate: the folder to write the packages to (a workspace's src/)",
    )


def run(args: argparse.Namespace) -> int:
    """Generate, install or show: the LCM types' packages with --lcm-types (or for generate),
    else the Jazzy packages PyPI lacks (tf2_msgs). Each step (a package written, built) is a line;
    on a terminal the build under way stays below with its running time and a bar of its build
    steps, on a pipe a line per tenth of them once it has run 2 s (`util/progress.py`)."""
    if args.action != "install":  # quick: each line as it comes
        return _run(args, Steps(terminal=False))
    with steps() as told:  # builds of a minute or more: the one under way stays below
        return _run(args, told)


def _advanced(told: Steps) -> Callable[[str, int, int], None]:
    """How a package's build steps are told: `building drake_lcm_msgs: 40%: 56 of 140 build steps (6 s)`."""

    def advanced(name: str, done: int, total: int) -> None:
        told.part(
            f"viewer-bridge ros-interfaces: building {name}",
            done,
            total,
            lambda done: f"{done} of {total} build steps",
        )

    return advanced


def _run(args: argparse.Namespace, told: Steps) -> int:
    from viewer_bridge.ros_build import interfaces as ros_interfaces
    from viewer_bridge.ros_build.packages import closure
    from viewer_bridge.util.words import counted

    say = told.say
    if args.action == "generate":  # the LCM types' packages: the project's and Drake's, and --lcm-types'
        if args.output is None:
            raise UsageError("generate needs -o DIR")
        started = time.monotonic()
        documented = _lcm_ros_definitions(args.lcm_types, comments=True, warn=say)
        chosen = closure(ros_interfaces.packages(documented), args.names or None)
        total = sum(len(package.messages) for package in chosen)
        words = counted(total, "type")
        with progress("viewer-bridge ros-interfaces", "writing", total, lambda done: f"{done} of {words}",
                      started=started) as advance:  # fmt: skip
            folders = ros_interfaces.generate_packages(
                documented, args.output, only=args.names or None, wrote=lambda _: advance(1)
            )
        for folder in folders:
            print(folder)
            written = sorted(path.stem for path in (folder / "msg").glob("*.msg"))
            say(f"viewer-bridge ros-interfaces: wrote {folder.name}: {counted(len(written), 'type')} "
                f"({', '.join(written)})")  # fmt: skip
        return 0
    if args.lcm_types:
        definitions = _lcm_ros_definitions(args.lcm_types)
        if args.action == "install":
            ros_interfaces.build(
                definitions,
                log=say,
                only=args.names or None,
                confirm=_confirm(args.yes, told),
                advanced=_advanced(told),
            )
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
    if args.action == "status":  # the Jazzy packages PyPI lacks, then every other package built here
        absent = ros_interfaces.missing()
        for name in args.names or ros_interfaces.INTERFACES:
            print(f"{name}: {'missing' if name in absent else 'installed'} in {sys.prefix}")
        if not args.names:
            for name in ros_interfaces.built():
                if name not in ros_interfaces.INTERFACES:
                    print(f"{name}: installed (LCM types) in {sys.prefix}")
        return 0
    ros_interfaces.install(
        args.names or None, log=say, confirm=_confirm(args.yes, told), advanced=_advanced(told)
    )
    return 0


def _confirm(yes: bool, told: Steps | None = None) -> Callable[[Sequence[str]], bool]:
    """What `install` asks before pip installs the wheels a build needs: yes with --yes; the user
    when standard input is a terminal; otherwise a refusal naming --yes (a script never installs
    about a hundred distributions unasked)."""

    def confirm(wheels: Sequence[str]) -> bool:
        if yes:
            return True
        what = f"pip install {' '.join(wheels)} (and what they need) into {sys.prefix}"
        if not sys.stdin.isatty():
            raise UsageError(
                f"building needs {what}: run again with --yes to allow it, or pip install "
                "'viewer-bridge[ros,ros-build]' first"
            )
        with told.paused() if told is not None else contextlib.nullcontext():  # no spinner over the question
            answer = input(f"viewer-bridge ros-interfaces: {what}? [y/N] ")
        return answer.strip().lower() in ("y", "yes")

    return confirm


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
        if library.drake_left_out:
            warn(DRAKE_LEFT_OUT)
    return dict(library.ros_definitions(comments=comments))
