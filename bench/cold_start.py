"""Benchmark: a per-draw translation back to back, and after a 1 ms sleep (as the bridge runs it).

Run: .venv/bin/python bench/cold_start.py [--draws 600]

The bridge translates a draw right after its LCM thread wakes up for it. On a VM a wake-up
leaves the caches cold, so a translation costs more in the running bridge than back to back.
This process, pinned to CPU 0, runs each per-draw translator of the default config (world-frame
markers, TF, poses) on a 1000-link scene: once with the draws back to back, once with a 1 ms
sleep before each, and prints the median time per draw of each and their ratio.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

from router import frame, scene

from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.translators.base import Translator
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.translators.types import LOAD_TYPE
from viewer_bridge.transports.base import Received

TRANSLATORS_PER_DRAW = ("drake_to_marker_array", "drake_to_tf", "drake_to_pose_array")


def loaded(name: str, load: bytes) -> Translator:
    """The translator with the scene loaded, as a route has it before the draws come."""
    translator = TRANSLATORS.get(name)({})
    if LOAD_TYPE in translator.reads:
        message = Received("DRAKE_VIEWER_LOAD_ROBOT", load)
        translator.observe(message)
        translator.translate(message)
    return translator


def median_per_draw(translator: Translator, draws: list[bytes], count: int, sleep_s: float) -> float:
    """Median seconds of `observe` + `translate` per draw, with `sleep_s` before each."""
    times = []
    for index in range(count):
        if sleep_s:
            time.sleep(sleep_s)
        message = Received("DRAKE_VIEWER_DRAW", draws[index % len(draws)])
        started = time.perf_counter()
        translator.observe(message)
        translator.translate(message)
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--draws", type=int, default=600)
    args = parser.parse_args()
    os.sched_setaffinity(0, {0})
    the_scene = scene(1000)
    names = tuple(link.name for link in the_scene.links)
    load = load_from_scene(the_scene).encode()
    draws = [DrawEncoder().encode(frame(names, sequence)) for sequence in range(1, 51)]
    print(f"{'translator':<24} {'back to back':>13} {'after 1 ms sleep':>17} {'ratio':>6}")
    for name in TRANSLATORS_PER_DRAW:
        translator = loaded(name, load)
        warm = median_per_draw(translator, draws, args.draws, 0.0)
        cold = median_per_draw(translator, draws, args.draws, 0.001)
        print(f"{name:<24} {warm * 1e6:10.1f} us {cold * 1e6:14.1f} us {cold / warm:5.1f}x")


if __name__ == "__main__":
    main()
