"""Benchmark: lcmt_viewer_draw decode/encode, viewer-bridge against lcm-gen's generated Python.

Run: .venv/bin/python bench/draw_codec.py [--links 10 100 1000 10000]
Both sides run in this process on the same bytes; ratios are baseline time / our time.
The baseline is the Python that `lcm-gen --python` (from the `lcm` wheel) writes for our schema.
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

import numpy as np

from bridge.formats.drake import DrawDecoder, DrawEncoder
from bridge.lcmcodec import DRAW, SCHEMA_DIR
from bridge.scene import LinkPoses


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


def frame(links: int, seed: int = 0) -> LinkPoses:
    rng = np.random.default_rng(seed)
    quaternions = rng.normal(size=(links, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    return LinkPoses(
        timestamp_ms=1234,
        names=tuple(f"plant::robot{i % 7}::link_{i}" for i in range(links)),
        robot_nums=(np.arange(links) % 7).astype(np.int32),
        positions=rng.normal(size=(links, 3)),
        quaternions_wxyz=quaternions,
    )


def seconds_per_call(function: Callable[[], object], budget: float) -> float:
    timer = timeit.Timer(function)
    number, _ = timer.autorange()
    repeats = max(3, int(budget / max(timer.timeit(number), 1e-9)))
    return min(timer.repeat(repeat=min(repeats, 7), number=number)) / number


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--links", type=int, nargs="+", default=[10, 100, 1000, 10000])
    parser.add_argument("--budget", type=float, default=0.3, help="seconds per measurement")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        baseline_class = lcm_gen_draw_class(Path(folder))
    print("lcmt_viewer_draw, microseconds per message (ratio = lcm-gen time / ours)")
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
