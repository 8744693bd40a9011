"""Benchmark: lcmt_viewer_draw decode/encode, viewer-bridge against lcm-gen's generated Python.

Run: .venv/bin/python bench/draw_codec.py [--links 10 100 1000 10000] [--quick]
Both sides run in this process on the same bytes; ratios are baseline time / our time.
The baseline is the Python that `lcm-gen --python` (from the `lcm` wheel) writes for our schema.
`measures()` gives issue 15's goal 1 as rows (fast decode of a 1000-link draw >= 100x lcm-gen,
of a 10-link draw >= 2x), each timed as ours and baseline alternately, the best of each kept.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sysconfig
import tempfile
import timeit
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from common import Measure, Size, best_of, frame  # bench/ is on sys.path when run as a script

from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.lcmcodec.codecs import DRAW, SCHEMA_DIR


def lcm_gen_draw_class(folder: Path) -> Any:
    lcm_gen = Path(sysconfig.get_paths()["purelib"]) / "bin" / "lcm-gen"
    subprocess.run(
        [str(lcm_gen), "--python", "--ppath", str(folder), str(SCHEMA_DIR / "lcmt_viewer_draw.lcm")],
        check=True,
    )
    spec = importlib.util.spec_from_file_location("lcmgen_draw", folder / "drake" / "lcmt_viewer_draw.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.lcmt_viewer_draw


def seconds_per_call(function: Callable[[], object], budget: float) -> float:
    """Seconds per call of `function`, the best of repeats that fill about `budget` seconds; a
    budget of 0 times one call (a smoke run, where only that it runs matters)."""
    timer = timeit.Timer(function)
    if budget <= 0:
        return timer.timeit(1)
    number, _ = timer.autorange()
    repeats = max(3, int(budget / max(timer.timeit(number), 1e-9)))
    return min(timer.repeat(repeat=min(repeats, 7), number=number)) / number


def paired(ours: Callable[[], object], baseline: Callable[[], object], size: Size) -> tuple[float, float]:
    """Seconds per call of both, measured in alternating rounds (the machine's load drifts), the
    best of each."""
    number_ours = max(1, int(0.02 / max(best_of(ours, 1, 10), 1e-9)))
    number_base = max(1, int(0.02 / max(best_of(baseline, 1, 3), 1e-9)))
    ours_best = base_best = float("inf")
    for _ in range(size.pick(full=8, quick=3, smoke=1)):
        ours_best = min(ours_best, best_of(ours, 5, number_ours))
        base_best = min(base_best, best_of(baseline, 3, number_base))
    return ours_best, base_best


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Goal 1: the fast decode of a 1000-link and a 10-link draw against lcm-gen's decode."""
    with tempfile.TemporaryDirectory() as folder:
        baseline_class = lcm_gen_draw_class(Path(folder))
    rows = []
    for links, goal in ((1000, 100.0), (10, 2.0)):
        data = DrawEncoder().encode(frame(links))
        decoder = DrawDecoder()
        decoder.decode(data)  # steady state: the names are known from the previous frame
        ours, base = paired(partial(decoder.decode, data), partial(baseline_class.decode, data), size)
        rows.append(
            Measure(
                f"decode lcmt_viewer_draw, {links} links, vs lcm-gen",
                ours * 1e6,
                base * 1e6,
                "us",
                f"ratio >= {goal:g}x",
                base / ours >= goal,
            )
        )
    return rows


def print_measures(rows: list[Measure]) -> None:
    header = f"{'measure':<58} {'ours':>9} {'baseline':>10} {'ratio':>7}  {'goal':<16} met"
    print(header)
    print("-" * len(header))
    for row in rows:
        ratio = f"{row.baseline / row.ours:6.1f}x" if row.baseline else "      -"
        baseline = f"{row.baseline:10.1f}" if row.baseline is not None else f"{'-':>10}"
        met = "-" if row.met is None else ("yes" if row.met else "NO")
        print(f"{row.name:<58} {row.ours:9.2f} {baseline} {ratio}  {row.goal:<16} {met}   ({row.unit})")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--links", type=int, nargs="+", default=[10, 100, 1000, 10000])
    parser.add_argument("--budget", type=float, default=0.3, help="seconds per measurement")
    parser.add_argument("--quick", action="store_true", help="only the goal rows, fewer rounds")
    args = parser.parse_args()
    print_measures(measures(Size.QUICK if args.quick else Size.FULL))
    if args.quick:
        return
    with tempfile.TemporaryDirectory() as folder:
        baseline_class = lcm_gen_draw_class(Path(folder))
    print("\nlcmt_viewer_draw, microseconds per message (ratio = lcm-gen time / ours)")
    header = (
        f"{'links':>6} {'bytes':>8} | {'lcm-gen dec':>11} {'generic dec':>11} {'fast dec':>9} {'fast ratio':>10} | "
        f"{'lcm-gen enc':>11} {'fast enc':>9} {'enc ratio':>9}"
    )
    print(header)
    print("-" * len(header))
    for links in args.links:
        poses = frame(links)
        data = DrawEncoder().encode(poses)
        baseline_message = baseline_class.decode(data)
        assert baseline_message.encode() == data == DRAW.encode(DRAW.decode(data))
        decoder = DrawDecoder()
        decoder.decode(data)  # steady state: the name block is known from the previous frame
        encoder = DrawEncoder()
        encoder.encode(poses)
        # A new frame's positions arrive as new arrays every time, as from a simulation.
        next_poses = frame(links, seed=1)
        calls: dict[str, Callable[[], object]] = {
            "lcm-gen dec": partial(baseline_class.decode, data),
            "generic dec": partial(DRAW.decode, data),
            "fast dec": partial(decoder.decode, data),
            "lcm-gen enc": baseline_message.encode,
            "fast enc": partial(encoder.encode, next_poses),
        }
        times = {name: seconds_per_call(call, args.budget) for name, call in calls.items()}
        us = {key: value * 1e6 for key, value in times.items()}
        print(
            f"{links:>6} {len(data):>8} | {us['lcm-gen dec']:>11.1f} {us['generic dec']:>11.1f} {us['fast dec']:>9.2f} "
            f"{times['lcm-gen dec'] / times['fast dec']:>9.0f}x | {us['lcm-gen enc']:>11.1f} {us['fast enc']:>9.2f} "
            f"{times['lcm-gen enc'] / times['fast enc']:>8.0f}x"
        )
    # The first frame (or one whose names changed) pays for parsing the names once.
    poses = frame(1000)
    data = DrawEncoder().encode(poses)
    cold = seconds_per_call(lambda: DrawDecoder().decode(data), args.budget)
    base = seconds_per_call(lambda: baseline_class.decode(data), args.budget)
    print(
        f"\n1000 links, names not cached (first frame): fast {cold * 1e6:.1f} us, lcm-gen {base * 1e6:.1f} us, "
        f"ratio {base / cold:.1f}x"
    )


if __name__ == "__main__":
    main()
