"""Two checkouts' benchmarks in one run: this one and another (e.g. a restructure's starting commit
in a git worktree), script by script, alternating, so that both meet the same machine.

Run: .venv/bin/python bench/compare.py OTHER_CHECKOUT [--quick] [--only NAME ...] [--rounds N]

Each script of bench/all.py runs in a child process per checkout (its own `bridge` on
PYTHONPATH), `--rounds` times each, the two sides taking turns. The table gives each row's ratio
to its own baseline (measured in the same process; `x`) and its own figure, for both checkouts,
with half their spread over the rounds, and the change: a restructure whose changes stay within
the spread changed nothing measurable.

Both sides meet the same allocator: each child first frees one 31 MiB block, which raises glibc's
mmap threshold to that size and its trim threshold to twice it (as all.py's process is once its
first scripts have freed their big buffers). Without it, a row whose temporaries take a few MB
(point_cloud's) hands them back to the kernel and faults them in again on every call, by an
amount set by where the heap's top happens to lie: 1234 or 1333 page faults a call for the same
code, two thirds of the row's time, in the kernel.

Where things lie in memory moves a short row by a few percent, and without help it is the same
in every round of a checkout (its imports map the same libraries in the same order and fill the
heap the same way): the kept-layout JointState move takes 226 to 245 ns for the same program by
its address modulo 64 alone, and that row read 0.351 against 0.369 us with the same instructions
a call. So each child first reserves 4 to 8 MiB of address space and keeps a heap block, both of
random size: the libraries loaded afterwards and the blocks lie elsewhere each round, and that
shows as spread.

A script that the other checkout has without `measures` (it predates them) is measured there by
this checkout's script, on that checkout's code and bench helpers.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
CHILD = """
import mmap, random
# Kept: where the code loaded next and the heap's blocks lie differs each round (the docstring says why).
shift = mmap.mmap(-1, random.randrange(1024, 2048) * mmap.PAGESIZE)
bytes(31 << 20)  # freed at once: glibc's thresholds raised
heap_shift = bytes(random.randrange(1024, 1024 + 4096, 16))
import dataclasses, importlib.util, inspect, json, sys
sys.path[:0] = [sys.argv[1]]
if len(sys.argv) > 4:  # this checkout's script, on the other checkout's code
    spec = importlib.util.spec_from_file_location(sys.argv[2], sys.argv[4])
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
else:
    module = __import__(sys.argv[2])
quick = sys.argv[3] == "1"
if "size" in inspect.signature(module.measures).parameters:
    from common import Size
    rows = module.measures(Size.QUICK if quick else Size.FULL)
else:  # a checkout from before common.Size: measures(quick)
    rows = module.measures(quick=quick)
print("ROWS" + json.dumps([dataclasses.asdict(row) for row in rows]))
"""


def scripts(checkout: Path) -> list[str]:
    """The scripts bench/all.py runs, in its order."""
    code = "import sys; sys.path[:0] = [sys.argv[1]]; import all; print(' '.join(all.scripts()))"
    found = subprocess.run([sys.executable, "-c", code, str(checkout / "bench")], check=True, capture_output=True,
                           text=True, env=_environment(checkout)).stdout  # fmt: skip
    return found.split()


def _environment(checkout: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": f"{checkout}:{checkout / 'bench'}"}


def measure(checkout: Path, script: str, quick: bool) -> list[dict[str, object]]:
    """One script's rows as `checkout` measures them, in a child process: with its own script, or
    with this checkout's where its own has no `measures`."""
    own = checkout / "bench" / f"{script}.py"
    borrowed = [] if "\ndef measures(" in own.read_text() else [str(HERE / f"{script}.py")]
    result = subprocess.run([sys.executable, "-c", CHILD, str(checkout / "bench"), script, "1" if quick else "0",
                             *borrowed], capture_output=True, text=True, env=_environment(checkout),
                            cwd=checkout)  # fmt: skip
    for line in result.stdout.splitlines():
        if line.startswith("ROWS"):
            return list(json.loads(line[4:]))
    raise SystemExit(f"{checkout}: bench/{script}.py failed:\n{result.stderr[-2000:]}")


def figures(row: dict[str, object]) -> list[tuple[str, str, float]]:
    """A row's ratio to its own baseline (where it has one) and its own figure, each with its unit."""
    ours, baseline = row.get("ours"), row.get("baseline")
    if not isinstance(ours, (int, float)) or not ours:
        return []
    found = [("", f" {row.get('unit', '')}", float(ours))]
    if isinstance(baseline, (int, float)) and baseline:
        found.insert(0, (" (ratio)", "x", float(baseline) / float(ours)))
    return found


def _cell(values: list[float], unit: str) -> str:
    if not values:
        return "-"
    middle = sorted(values)[len(values) // 2]
    spread = (max(values) - min(values)) / middle * 100 if middle else 0.0
    return f"{middle:.3g}{unit} ±{spread / 2:.0f}%"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("other", type=Path, help="the other checkout (a git worktree)")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--only", nargs="*")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    here, other = HERE.parent, args.other.resolve()
    found: dict[tuple[str, str, str], dict[str, list[float]]] = {}
    for script in scripts(here):
        if args.only and script not in args.only:
            continue
        sides = [("this", here)] + ([("other", other)] if (other / "bench" / f"{script}.py").exists() else [])
        for _ in range(args.rounds):
            for side, checkout in reversed(sides):
                print(f"--- {side}: bench/{script}.py", file=sys.stderr, flush=True)
                for row in measure(checkout, script, args.quick):
                    for label, unit, value in figures(row):
                        key = (script, f"{row['name']}{label}", unit)
                        found.setdefault(key, {}).setdefault(side, []).append(value)
    print(f"| script | measure | {other.name} | this checkout | change |")
    print("|---|---|---:|---:|---:|")
    for (script, name, unit), values in found.items():
        before, after = values.get("other", []), values.get("this", [])
        change = "-"
        if before and after:
            change = f"{(sorted(after)[len(after) // 2] / sorted(before)[len(before) // 2] - 1) * 100:+.0f}%"
        print(f"| {script} | {name} | {_cell(before, unit)} | {_cell(after, unit)} | {change} |")


if __name__ == "__main__":
    main()
