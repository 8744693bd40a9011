"""`viewer-bridge convert BAG OUT.lcmlog`: a ROS 2 bag into an LCM log (viewer_bridge/cli/bag_to_lcm.py).
`convert` comes here when its input is a ROS 2 bag (an MCAP file or a rosbag2 folder) and its
output an `.lcmlog`; an LCM log in takes `log_convert`'s way."""

from __future__ import annotations

import argparse
import os
import sys
import threading
from pathlib import Path
from typing import Any

from viewer_bridge.cli.bag_to_lcm import bag_to_lcm, is_ros_bag
from viewer_bridge.errors import UsageError


def input_path(text: str) -> str:
    """A file (an LCM log or an MCAP) or a rosbag2 folder, that exists and can be read."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such file or folder")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text}: not readable")
    return text


def wanted(args: Any) -> bool:
    """Whether `convert`'s input is a ROS 2 bag (then the output must be an .lcmlog)."""
    if not is_ros_bag(args.log):
        if args.topics or args.lcm_types_out:
            raise UsageError("--topics and --lcm-types-out are for a ROS 2 bag in")
        return False
    if Path(args.mcap).suffix != ".lcmlog":
        raise UsageError(f"{args.log} is a ROS 2 bag: the output must be an .lcmlog file")
    return True


def run(args: Any, stop: threading.Event | None = None) -> int:
    """Convert; print messages per topic, then each topic left out and each with bad messages; a
    damaged bag (cut short, rows that hold no message, chunks skipped) exits 1, having converted what it could."""
    result = bag_to_lcm(
        args.log,
        args.mcap,
        topics=args.topics,
        lcm_types_out=args.lcm_types_out,
        force=args.force,
        stop=stop,
        progress=True,
    )
    for topic, channel in result.channels.items():
        print(f"{result.written[topic]:8d}  {topic} -> {channel}")
    for topic, reason in result.skipped.items():
        print(f"viewer-bridge convert: {topic} left out: {reason}", file=sys.stderr)
    for topic, count in result.bad.items():
        print(f"viewer-bridge convert: {topic}: {count} messages did not convert, the first: {result.first_error[topic]}",
              file=sys.stderr)  # fmt: skip
    for topic, count in result.damaged.items():
        print(f"viewer-bridge convert: {topic}: {count} rows of the bag are damaged, the first: "
              f"{result.first_damage[topic]}",
              file=sys.stderr)  # fmt: skip
    if result.damaged_chunks:
        print(f"viewer-bridge convert: {args.log}: {len(result.damaged_chunks)} chunks are damaged and skipped, "
              f"the first: {result.damaged_chunks[0]}",
              file=sys.stderr)  # fmt: skip
    for why in result.unread_summaries:  # nothing lost: said, not failed
        print(f"viewer-bridge convert: {args.log}: {why}", file=sys.stderr)
    if result.cut is not None:
        print(f"viewer-bridge convert: {args.log} is damaged: {result.cut}", file=sys.stderr)
    for path in result.lcm_files:
        print(path)
    return 0 if result.complete else 1
