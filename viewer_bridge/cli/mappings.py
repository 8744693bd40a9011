"""`viewer-bridge mappings`: the mapping reference (mappings/REFERENCE.md), made from the tables."""

from __future__ import annotations

import argparse

from viewer_bridge.cli.arguments import AddCommand
from viewer_bridge.formats.mappings import format_names, reference_markdown


def add_command(add: AddCommand) -> None:
    """The `mappings` command (it takes no arguments), on the parser `add` makes."""
    add("mappings", help="print the mapping reference (mappings/REFERENCE.md) from the tables")


def run(args: argparse.Namespace) -> int:
    """Print the reference as Markdown."""
    print(reference_markdown(format_names()), end="")
    return 0
