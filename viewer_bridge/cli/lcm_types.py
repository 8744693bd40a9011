"""`viewer-bridge lcm-types generate`: ROS 2 message types as `.lcm` files that lcm-gen reads
(docs/PROTOCOLS.md, "Any ROS 2 type, onto LCM")."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

from viewer_bridge.cli.arguments import AddCommand
from viewer_bridge.errors import UsageError
from viewer_bridge.lcmcodec.from_ros import load_ros_definitions, map_ros_types
from viewer_bridge.util.progress import progress


def add_command(add: AddCommand) -> None:
    """The `lcm-types` command's arguments, on the parser `add` makes."""
    command = add("lcm-types", help="write ROS 2 message types as .lcm files (for lcm-gen)")
    command.add_argument("action", choices=["generate"])
    command.add_argument(
        "--ros-types",
        nargs="+",
        required=True,
        metavar="SRC",
        help="ROS 2 types (pkg/msg/Name), packages of the Jazzy store (sensor_msgs), or .msg files and folders",
    )
    command.add_argument(
        "-o", "--output", type=Path, required=True, metavar="DIR", help="where the .lcm files go"
    )


def run(args: Any) -> int:
    """Write the files (`DIR/<package>/<Name>.lcm`), print each path; a type that cannot be
    mapped is one line on stderr with its reason, and makes the exit status 1; a last line on
    stderr counts what was written and left out."""
    if args.action != "generate":
        raise UsageError(f"unknown action {args.action}")
    started = time.monotonic()
    definitions, wanted = load_ros_definitions(args.ros_types)
    mapping = map_ros_types(definitions, wanted)
    from viewer_bridge.util.words import counted

    words = counted(len(mapping.texts), "type")
    # the types are read and mapped, then written: long work (a whole store) says how far, past 2 s
    with progress("viewer-bridge lcm-types", "writing", len(mapping.texts), lambda done: f"{done} of {words}",
                  started=started) as advance:  # fmt: skip
        written = mapping.write(args.output, wrote=lambda _: advance(1))
    for path in written:
        print(path)
    for ros_name, reason in mapping.refused.items():
        print(f"viewer-bridge lcm-types: {ros_name} not mapped: {reason}", file=sys.stderr)
    left_out = f", {counted(len(mapping.refused), 'type')} left out (above)" if mapping.refused else ""
    print(
        f"viewer-bridge lcm-types: wrote {counted(len(written), 'type')} into {args.output}{left_out}",
        file=sys.stderr,
    )
    return 1 if mapping.refused else 0
