"""Every benchmark in one run, one table: measure, ours, baseline, ratio, goal, met.

Run: .venv/bin/python bench/all.py [--quick] [--only NAME ...] [--write-docs]

Each script in bench/ that has a `measures(quick)` function is run in this process, in
file-name order but with the router last: it keeps both cores busy for minutes, and nothing
should be measured in its wake. Each script measures its own baseline in the same run: lcm-gen's
Python, rclpy message objects, protobuf's Python API, RenderEngineVtk, a bare passthrough route.
`--write-docs` writes the table, with the machine it ran on, into docs/benchmarks.md between its
`bench:begin` and `bench:end` markers.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import sys
import time
from pathlib import Path

from common import Measure

HERE = Path(__file__).resolve().parent
PAGE = HERE.parent / "docs" / "benchmarks.md"  # the benchmarks guide
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


def write_docs(text: str, page: Path = PAGE) -> None:
    """The table into the benchmarks guide, in place of the one between its markers."""
    old = page.read_text()
    head, begin, rest = old.partition(BEGIN)
    _, end, tail = rest.partition(END)
    if not begin or not end:
        raise SystemExit(f"{page} has no {BEGIN} ... {END} section to write into")
    page.write_text(f"{head}{BEGIN}\n{text}\n{END}{tail}")


def machine() -> str:
    """The machine a run measured: CPU model, the cores this process may use, memory, Python."""
    model = next((line.split(":", 1)[1].strip() for line in _lines("/proc/cpuinfo") if line.startswith("model name")),
                 platform.processor() or platform.machine())  # fmt: skip
    memory = next((int(line.split()[1]) // 1024 // 1024 for line in _lines("/proc/meminfo")
                   if line.startswith("MemTotal:")), None)  # fmt: skip
    cores = len(os.sched_getaffinity(0))
    return (f"{model} ({platform.machine()}), {cores} core{'s' if cores != 1 else ''}"
            f"{f', {memory} GiB' if memory else ''}, {platform.system()} {platform.release()}, "
            f"Python {platform.python_version()}")  # fmt: skip


def _lines(path: str) -> list[str]:
    try:
        return Path(path).read_text().splitlines()
    except OSError:
        return []


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer repeats and shorter runs")
    parser.add_argument("--only", nargs="*", help="these scripts only (file names without .py)")
    parser.add_argument("--write-docs", action="store_true", help="write the table into docs/benchmarks.md")
    args = parser.parse_args()
    rows: list[tuple[str, Measure]] = []
    started = time.monotonic()
    for name in scripts():
        if args.only and name not in args.only:
            continue
        print(f"--- bench/{name}.py", file=sys.stderr, flush=True)
        module = importlib.import_module(name)
        rows += [(name, row) for row in module.measures(quick=args.quick)]
    where = machine()
    rows.sort(key=lambda row: row[0])  # the table in file-name order, whatever ran first
    text = (f"{table(rows)}\n\nRatio = baseline / ours (above 1: ours is faster). `bench/all.py"
            f"{' --quick' if args.quick else ''}` on {time.strftime('%Y-%m-%d')}, {time.monotonic() - started:.0f} s, on "
            f"{where}.")  # fmt: skip
    print(text)
    if args.write_docs:
        write_docs(text)


if __name__ == "__main__":
    main()
