"""Every benchmark in one run, one table: measure, ours, baseline, ratio, goal, met.

Run: .venv/bin/python bench/all.py [--quick | --smoke] [--only NAME ...] [--write-docs]

Each script in bench/ that has a `measures(size)` function is run in this process, in
file-name order but with the router last: it keeps both cores busy for minutes, and nothing
should be measured in its wake. Each script measures its own baseline in the same run: lcm-gen's
Python, rclpy message objects, protobuf's Python API, RenderEngineVtk, a bare passthrough route.
`--write-docs` writes the table, with the machine it ran on, into docs/benchmarks.md between its
`bench:begin` and `bench:end` markers.

`--smoke` runs every row at tiny sizes (`common.Size.SMOKE`): its figures mean nothing, but it
shows in a minute or two that every script still runs and produces its rows
(tests/test_bench_smoke.py runs it). A script that fails, returns no row or a row without a
figure is reported by name after the others have run, and the exit code is 1.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import platform
import sys
import time
import traceback
from pathlib import Path

from common import Measure, Size

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


def run_script(name: str, size: Size) -> tuple[list[Measure], str | None]:
    """The rows of bench/`name`.py at `size`, and what is wrong with them (None: nothing)."""
    started = time.monotonic()
    print(f"--- bench/{name}.py", file=sys.stderr, flush=True)
    try:
        rows: list[Measure] = importlib.import_module(name).measures(size)
    except Exception:  # any failure of one script is reported with the others' results
        traceback.print_exc()
        return [], "failed (its traceback is above)"
    print(
        f"--- bench/{name}.py: {len(rows)} rows in {time.monotonic() - started:.1f} s",
        file=sys.stderr,
        flush=True,
    )
    if not rows:
        return rows, "returned no row"
    unmeasured = [row.name for row in rows if not math.isfinite(row.ours)]
    return rows, f"measured nothing for {unmeasured}" if unmeasured else None


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sizes = parser.add_mutually_exclusive_group()
    sizes.add_argument("--quick", action="store_true", help="fewer repeats and shorter runs")
    sizes.add_argument(
        "--smoke", action="store_true", help="every row at tiny sizes: only checks that each is produced"
    )
    parser.add_argument("--only", nargs="*", help="these scripts only (file names without .py)")
    parser.add_argument("--write-docs", action="store_true", help="write the table into docs/benchmarks.md")
    args = parser.parse_args()
    size = Size.SMOKE if args.smoke else Size.QUICK if args.quick else Size.FULL
    if args.write_docs and size is Size.SMOKE:
        parser.error("a smoke run's figures mean nothing: it cannot --write-docs")
    rows: list[tuple[str, Measure]] = []
    problems: dict[str, str] = {}
    started = time.monotonic()
    for name in scripts():
        if args.only and name not in args.only:
            continue
        produced, problem = run_script(name, size)
        rows += [(name, row) for row in produced]
        if problem is not None:
            problems[name] = problem
    where = machine()
    rows.sort(key=lambda row: row[0])  # the table in file-name order, whatever ran first
    text = (f"{table(rows)}\n\nRatio = baseline / ours (above 1: ours is faster). `bench/all.py"
            f"{'' if size is Size.FULL else ' --' + size.value}` on {time.strftime('%Y-%m-%d')}, "
            f"{time.monotonic() - started:.0f} s, on {where}.")  # fmt: skip
    print(text)
    for name, problem in problems.items():
        print(f"bench/{name}.py {problem}", file=sys.stderr)
    if problems:
        raise SystemExit(1)  # and nothing written into the docs
    if args.write_docs:
        write_docs(text)


if __name__ == "__main__":
    main()
