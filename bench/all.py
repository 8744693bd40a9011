"""Every benchmark in one run, one table: measure, ours, baseline, ratio, goal, met.

Run: .venv/bin/python bench/all.py [--quick] [--only NAME ...] [--readme]

Each script in bench/ that has a `measures(quick)` function is run in this process, in
file-name order but with the router last: it keeps both cores busy for minutes, and nothing
should be measured in its wake. Each script measures its own baseline in the same run: lcm-gen's
Python, rclpy message objects, protobuf's Python API, RenderEngineVtk, a bare passthrough route.
`--readme` writes the table into README.md between its `bench:begin` and `bench:end` markers.
"""

from __future__ import annotations

import argparse
import importlib
import platform
import sys
import time
from pathlib import Path

from common import Measure

HERE = Path(__file__).resolve().parent
README = HERE.parent / "README.md"
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"


LAST = "router"  # the heaviest load: nothing is measured after it


def scripts() -> list[str]:
    """The bench scripts with a `measures` function (a cheap text check: nothing is imported yet),
    in the order they run."""
    return sorted(
        (path.stem for path in HERE.glob("*.py")
         if path.stem not in {"all", "common"} and "\ndef measures(" in path.read_text()),
        key=lambda name: (name == LAST, name),
    )  # fmt: skip


def _number(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.3g}" if abs(value) < 100 else f"{value:.0f}"


def table(rows: list[tuple[str, Measure]]) -> str:
    lines = ["| script | measure | ours | baseline | unit | ratio | goal | met |",
             "|---|---|---:|---:|---|---:|---|---|"]  # fmt: skip
    for script, row in rows:
        ratio = f"{row.baseline / row.ours:.1f}x" if row.baseline and row.ours else "-"
        met = "-" if row.met is None else ("yes" if row.met else "**no**")
        lines.append(f"| {script} | {row.name} | {_number(row.ours)} | {_number(row.baseline)} | {row.unit} "
                     f"| {ratio} | {row.goal} | {met} |")  # fmt: skip
    return "\n".join(lines)


def write_readme(text: str) -> None:
    readme = README.read_text()
    head, begin, rest = readme.partition(BEGIN)
    _, end, tail = rest.partition(END)
    if not begin or not end:
        raise SystemExit(f"README.md has no {BEGIN} ... {END} section to write into")
    README.write_text(f"{head}{BEGIN}\n{text}\n{END}{tail}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer repeats and shorter runs")
    parser.add_argument("--only", nargs="*", help="these scripts only (file names without .py)")
    parser.add_argument("--readme", action="store_true", help="write the table into README.md")
    args = parser.parse_args()
    rows: list[tuple[str, Measure]] = []
    started = time.monotonic()
    for name in scripts():
        if args.only and name not in args.only:
            continue
        print(f"--- bench/{name}.py", file=sys.stderr, flush=True)
        module = importlib.import_module(name)
        rows += [(name, row) for row in module.measures(quick=args.quick)]
    where = f"{platform.machine()}, {len(__import__('os').sched_getaffinity(0))} cores, Python {platform.python_version()}"
    rows.sort(key=lambda row: row[0])  # the table in file-name order, whatever ran first
    text = (f"{table(rows)}\n\nRatio = baseline / ours (above 1: ours is faster). `bench/all.py"
            f"{' --quick' if args.quick else ''}`, {where}, {time.monotonic() - started:.0f} s.")  # fmt: skip
    print(text)
    if args.readme:
        write_readme(text)


if __name__ == "__main__":
    main()
