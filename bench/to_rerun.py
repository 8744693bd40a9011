"""Benchmark: Drake draws -> Rerun, 1000 links, and 1 kHz x 1000 links into an .rrd file on one core.

(Not named rerun.py: bench/ is on the import path, and would shadow the SDK's `rerun`.)

Run: .venv/bin/python bench/to_rerun.py [--seconds 10] [--quick] [--baseline-checkout PATH]

`measures()` gives issues 34's and 42's goals as rows:

* CPU per 1000-link draw into an .rrd file, this process's every thread (the SDK's batcher and
  file writer included, so each side pays for what it sends): the bridge's `drake_to_rerun` and
  rerun transport (draw bytes -> the SDK's chunk -> `send_chunks`), against the SDK alone logging
  the same draw as one batch of 1000 `Transform3D` rows (`rr.send_columns` of
  `Transform3D.columns`, from the arrays in hand: no LCM to decode). Interleaved rounds, the
  best of each. Goal: no more than the SDK alone.
* the same draw to the Rerun calls in wall time, against one `rr.log` per link (the way a Rerun
  example logs a robot): goal >= 10x.
* (unless quick) the bridge as a process pinned to CPU 0 (this process, the publisher, pinned to
  the other core) with one `drake_to_rerun` route into an .rrd file, fed 1000-link draws over LCM
  at 1 kHz: its CPU time per draw (from /proc), and whether every draw is in the file (distinct
  sim_time values, read back with Rerun's reader). With `--baseline-checkout PATH`, the same
  live run follows with the bridge of another checkout (the code before a change), for a
  before/after on the same machine in the same minutes.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import numpy as np  # noqa: E402
import pyarrow.compute as pc  # noqa: E402
import rerun as rr  # noqa: E402
from common import Measure, Size, frame  # noqa: E402
from draw_codec import paired, print_measures  # noqa: E402
from rerun.chunk import RrdReader  # noqa: E402
from router import URL, Bridge, publish_at  # noqa: E402

from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder  # noqa: E402
from viewer_bridge.model.scene import LinkPoses, frame_name  # noqa: E402
from viewer_bridge.translators.drake_rerun import ROOT_FRAME  # noqa: E402
from viewer_bridge.translators.registry import TRANSLATORS  # noqa: E402
from viewer_bridge.translators.types import RERUN_CHUNKS_TYPE  # noqa: E402
from viewer_bridge.transports.base import Qos, Received, hand_over  # noqa: E402
from viewer_bridge.transports.lcm import LcmBus  # noqa: E402
from viewer_bridge.transports.rerun import RerunSettings, RerunTransport  # noqa: E402

CONFIG = """\
rerun: {{path: {path}, connect: ""}}
routes:
  - name: rerun
    source: {{transport: lcm, name: DRAKE_VIEWER_DRAW}}
    translator: drake_to_rerun
    destination: {{transport: rerun, name: /drake}}
    qos: {{depth: 1000}}
    rate: {{policy: all}}
"""

LINKS = 1000


def _draws(count: int) -> list[bytes]:
    """`count` 1000-link draws, each at its own time and poses (a recording of one draw again and
    again could be cheaper to write than a real one)."""
    encoder = DrawEncoder()
    return [encoder.encode(_at(frame(LINKS, seed=index), index)) for index in range(count)]


def _at(poses: LinkPoses, index: int) -> LinkPoses:
    return LinkPoses(index, poses.names, poses.robot_nums, poses.positions, poses.quaternions_wxyz)


class Side:
    """One way of getting draws into an .rrd file: `draw(bytes)`, and its recording stream."""

    def __init__(self, draw: Callable[[bytes], None], stream: rr.RecordingStream) -> None:
        self.draw = draw
        self.stream = stream

    def cpu_per_draw(self, draws: list[bytes]) -> float:
        """This process's CPU seconds per draw (every thread), until what was logged is written."""
        started = time.process_time()
        for data in draws:
            self.draw(data)
        self.stream.flush(timeout_sec=60.0)
        return (time.process_time() - started) / len(draws)


@contextlib.contextmanager
def bridge_side(folder: Path) -> Iterator[Side]:
    """What the router does with one draw on a `drake_to_rerun` route into an .rrd file."""
    translator = TRANSLATORS["drake_to_rerun"]({})  # made alone: a Shared (load cache) of its own
    transport = RerunTransport(RerunSettings(path=folder / "bridge.rrd", overwrite=True))
    publisher = transport.publisher("/drake", RERUN_CHUNKS_TYPE, Qos())

    def draw(data: bytes) -> None:
        for _, payload in translator.translate(Received("DRAKE_VIEWER_DRAW", data)):
            hand_over(publisher, payload)

    try:
        yield Side(draw, transport.stream)
    finally:
        transport.close()


@contextlib.contextmanager
def sdk_side(folder: Path, draws: list[bytes]) -> Iterator[Side]:
    """The SDK alone logging each draw as one batch of Transform3D rows, from the arrays in hand
    (the draws are decoded here, before any round)."""
    stream = rr.RecordingStream("bench_sdk", recording_id="bench_sdk")
    stream.save(folder / "sdk.rrd")
    decoder = DrawDecoder()
    decoded = {data: decoder.decode(data) for data in draws}
    children = [frame_name(name) for name in decoded[draws[0]].names]  # one set of names, as a robot has
    parents = [ROOT_FRAME] * len(children)

    def draw(data: bytes) -> None:
        poses = decoded[data]
        count = len(poses.names)
        rr.send_columns(
            "/drake/transforms",
            indexes=[rr.TimeColumn("sim_time", duration=np.full(count, poses.timestamp_ms, dtype="timedelta64[ms]")),
                     rr.TimeColumn("receive_time", timestamp=np.full(count, time.time_ns(), dtype="datetime64[ns]"))],
            columns=rr.Transform3D.columns(translation=poses.positions, quaternion=poses.quaternions_wxyz[:, [1, 2, 3, 0]],
                                           child_frame=children, parent_frame=parents),
            recording=stream,
        )  # fmt: skip

    try:
        yield Side(draw, stream)
    finally:
        stream.disconnect()


def cpu_measure(size: Size, folder: Path) -> Measure:
    """Issue 42's row: CPU per draw, the bridge's translator and transport against the SDK alone."""
    draws = _draws(size.pick(full=400, quick=300, smoke=10))
    with bridge_side(folder) as ours, sdk_side(folder, draws) as sdk:
        ours.cpu_per_draw(draws[:10])  # warm: the encoder's frame names, the SDK's first chunk
        sdk.cpu_per_draw(draws[:10])
        ours_best = sdk_best = float("inf")
        for _ in range(size.pick(full=6, quick=3, smoke=1)):  # interleaved: the machine's load drifts
            ours_best = min(ours_best, ours.cpu_per_draw(draws))
            sdk_best = min(sdk_best, sdk.cpu_per_draw(draws))
    return Measure("CPU per 1000-link draw into .rrd, bridge vs the SDK alone (one Transform3D batch)",
                   ours_best * 1e6, sdk_best * 1e6, "us", "<= the SDK alone", ours_best <= sdk_best)  # fmt: skip


def calls_measure(size: Size, folder: Path) -> Measure:
    """One 1000-link draw to the Rerun SDK: ours (one chunk) against one rr.log per link."""
    poses = frame(LINKS, seed=3)
    draw = DrawEncoder().encode(poses)
    baseline = rr.RecordingStream("bench_per_link", recording_id="bench_per_link")
    baseline.save(folder / "per_link.rrd")
    decoder = DrawDecoder()
    paths = [f"/drake/{name.replace('::', '/')}" for name in poses.names]

    def per_link() -> None:
        decoded = decoder.decode(draw)
        baseline.set_time("sim_time", duration=decoded.timestamp_ms / 1000)
        for path, position, (w, x, y, z) in zip(
            paths, decoded.positions, decoded.quaternions_wxyz, strict=True
        ):
            baseline.log(path, rr.Transform3D(translation=position, quaternion=(x, y, z, w)))

    with bridge_side(folder) as ours:
        fast, slow = paired(lambda: ours.draw(draw), per_link, size)
    baseline.disconnect()
    return Measure("draw -> Rerun, 1000 links, one chunk vs one log per link", fast * 1e6, slow * 1e6, "us",
                   "ratio >= 10x", slow / fast >= 10.0)  # fmt: skip


@contextlib.contextmanager
def on_core(core: int) -> Iterator[None]:
    """This process on `core` alone meanwhile (the publisher off the bridge's core)."""
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {core})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


def live(seconds: float, folder: Path, checkout: Path | None = None) -> dict[str, float]:
    """The bridge (of `checkout`, else this one) pinned to CPU 0, 1000-link draws at 1 kHz for
    `seconds`, into an .rrd file."""
    names = frame(LINKS).names
    path = folder / "live.rrd"
    path.unlink(missing_ok=True)
    bridge = Bridge(CONFIG.format(path=path), folder, core=0, source=checkout)
    bus = LcmBus(URL)
    time.sleep(2.0)  # the bridge's subscription joined (its start-up line came before)
    sent: dict[int, int] = {}
    cpu_before = bridge.cpu_seconds()
    with on_core(1 if (os.cpu_count() or 1) > 1 else 0):
        publisher = threading.Thread(target=publish_at, args=(bus, 1000.0, seconds, names, sent))
        publisher.start()
        publisher.join()

    taken_in = [-1]

    # nothing more came in since the last look, and all of it went out or was counted
    def caught_up() -> bool:
        stats = bridge.snapshot().get("rerun", {})
        if not stats or stats["messages_in"] != taken_in[0]:
            taken_in[0] = stats.get("messages_in", -1)
            return False
        return bool(stats["messages_out"] + stats["dropped"] + _errors(stats) >= stats["messages_in"])

    deadline = time.monotonic() + 60
    while not caught_up() and time.monotonic() < deadline:
        time.sleep(1.5)  # the bridge writes its stats once a second
    cpu = bridge.cpu_seconds() - cpu_before
    stats = bridge.snapshot()["rerun"]
    bridge.stop()
    bus.close()
    return {
        "sent": len(sent),
        "in": stats["messages_in"],
        "out": stats["messages_out"],
        "dropped": stats["dropped"],
        "errors": _errors(stats),
        "recorded": len(recorded_draws(path)),
        "cpu_us": cpu / max(stats["messages_out"], 1) * 1e6,
    }


def _errors(stats: dict) -> int:  # type: ignore[type-arg]
    return int(sum(stats.get("errors", {}).values()))


def recorded_draws(path: Path) -> set[int]:
    """The sim times (ns) of the draws an .rrd file holds, read back with Rerun's reader."""
    times: set[int] = set()
    for chunk in RrdReader(path).stream():
        if chunk.entity_path == "/drake/transforms":
            times.update(pc.unique(chunk.to_record_batch().column("sim_time").cast("int64")).to_pylist())
    return times


def live_measure(result: dict[str, float], whose: str = "") -> Measure:
    every = result["recorded"] == result["sent"]
    return Measure(f"bridge{whose} CPU per draw into .rrd, 1000 links at 1 kHz (one core), {result['recorded']:.0f}/"
                   f"{result['sent']:.0f} draws recorded", result["cpu_us"], None, "us",
                   "1 kHz, every draw", every and result["cpu_us"] < 1000.0)  # fmt: skip


def measures(size: Size = Size.FULL, seconds: float = 10.0) -> list[Measure]:
    with tempfile.TemporaryDirectory() as folder:
        rows = [cpu_measure(size, Path(folder)), calls_measure(size, Path(folder))]
        if size.every_row:
            rows.append(live_measure(live(size.pick(full=seconds, quick=seconds, smoke=0.5), Path(folder))))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--quick", action="store_true", help="only the in-process rows")
    parser.add_argument(
        "--baseline-checkout", type=Path, help="the live row again with this checkout's bridge"
    )
    args = parser.parse_args()
    size = Size.QUICK if args.quick else Size.FULL
    with tempfile.TemporaryDirectory() as folder:
        rows = [cpu_measure(size, Path(folder)), calls_measure(size, Path(folder))]
        if not args.quick:
            result = live(args.seconds, Path(folder))
            print("this checkout:", result)
            rows.append(live_measure(result))
            if args.baseline_checkout is not None:
                before = live(args.seconds, Path(folder), args.baseline_checkout.resolve())
                print(f"{args.baseline_checkout}:", before)
                rows.append(live_measure(before, f" ({args.baseline_checkout})"))
    print_measures(rows)


if __name__ == "__main__":
    main()
