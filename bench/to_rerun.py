"""Benchmark: Drake draws -> Rerun, 1000 links, and 1 kHz x 1000 links into an .rrd file on one core.

(Not named rerun.py: bench/ is on the import path, and would shadow the SDK's `rerun`.)

Run: .venv/bin/python bench/to_rerun.py [--seconds 10] [--quick]

`measures()` gives issue 34's speed goals as rows:

* a 1000-link draw to the Rerun calls: `drake_to_rerun` (draw bytes -> one chunk of 1000
  Transform3D rows -> the bytes the transport reads) and the rerun transport's publish (bytes ->
  `send_chunks`), against the same draw logged one `Transform3D` per link (`rr.log` per entity,
  the way a Rerun example logs a robot), both into an .rrd file: goal >= 10x;
* (unless quick) the bridge as a process pinned to CPU 0 with one `drake_to_rerun` route into an
  .rrd file, fed 1000-link draws over LCM at 1 kHz: its CPU time per draw (from /proc), and
  whether every draw is in the file (distinct sim_time values, read back with Rerun's reader).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
import pyarrow.compute as pc  # noqa: E402
import rerun as rr  # noqa: E402
from common import Measure, Size, frame  # noqa: E402
from draw_codec import paired, print_measures  # noqa: E402
from rerun.chunk import RrdReader  # noqa: E402
from router import URL, Bridge, publish_at  # noqa: E402

from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder  # noqa: E402
from viewer_bridge.translators import TRANSLATORS  # noqa: E402
from viewer_bridge.translators.types import RERUN_CHUNKS_TYPE  # noqa: E402
from viewer_bridge.transports.base import Qos, Received  # noqa: E402
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


def calls_measure(size: Size, folder: Path) -> Measure:
    """One 1000-link draw to the Rerun SDK: ours (one chunk) against one rr.log per link."""
    poses = frame(1000, seed=3)
    draw = DrawEncoder().encode(poses)
    translator = TRANSLATORS["drake_to_rerun"]({})  # made alone: a Shared (load cache) of its own
    transport = RerunTransport(RerunSettings(path=folder / "ours.rrd"))
    publisher = transport.publisher("/drake", RERUN_CHUNKS_TYPE, Qos())
    baseline = rr.RecordingStream("bench_per_link", recording_id="bench_per_link")
    baseline.save(folder / "per_link.rrd")
    decoder = DrawDecoder()
    paths = [f"/drake/{name.replace('::', '/')}" for name in poses.names]

    def ours() -> None:
        ((_, data),) = translator.translate(Received("DRAKE_VIEWER_DRAW", draw))
        publisher.publish(data)

    def per_link() -> None:
        decoded = decoder.decode(draw)
        baseline.set_time("sim_time", duration=decoded.timestamp_ms / 1000)
        for path, position, (w, x, y, z) in zip(paths, decoded.positions, decoded.quaternions_wxyz, strict=True):
            baseline.log(path, rr.Transform3D(translation=position, quaternion=(x, y, z, w)))

    fast, slow = paired(ours, per_link, size)
    transport.close()
    baseline.disconnect()
    return Measure("draw -> Rerun, 1000 links, one chunk vs one log per link", fast * 1e6, slow * 1e6, "us",
                   "ratio >= 10x", slow / fast >= 10.0)  # fmt: skip


def live(seconds: float, folder: Path) -> dict[str, float]:
    """The bridge pinned to CPU 0, 1000-link draws at 1 kHz for `seconds`, into an .rrd file."""
    names = frame(1000).names
    path = folder / "live.rrd"
    bridge = Bridge(CONFIG.format(path=path), folder, core=0)
    bus = LcmBus(URL)
    time.sleep(2.0)
    sent: dict[int, int] = {}
    cpu_before = bridge.cpu_seconds()
    publisher = threading.Thread(target=publish_at, args=(bus, 1000.0, seconds, names, sent))
    publisher.start()
    publisher.join()
    deadline = time.monotonic() + 60  # until the route has translated all it took in
    while time.monotonic() < deadline:
        stats = bridge.snapshot().get("rerun", {})
        done = stats and stats["messages_out"] + stats.get("dropped", 0) >= stats["messages_in"] >= len(sent)
        if done:
            break
        time.sleep(0.5)
    cpu = bridge.cpu_seconds() - cpu_before
    stats = bridge.snapshot()["rerun"]
    bridge.stop()
    bus.close()
    times = set()
    for chunk in RrdReader(path).stream():
        if chunk.entity_path == "/drake/transforms":
            times.update(pc.unique(chunk.to_record_batch().column("sim_time")).to_pylist())
    return {
        "sent": len(sent),
        "in": stats["messages_in"],
        "out": stats["messages_out"],
        "dropped": stats["dropped"],
        "recorded": len(times),
        "cpu_us": cpu / max(stats["messages_out"], 1) * 1e6,
    }


def live_measure(result: dict[str, float]) -> Measure:
    every = result["recorded"] == result["sent"]
    return Measure(f"bridge CPU per draw into .rrd, 1000 links at 1 kHz (one core), {result['recorded']:.0f}/"
                   f"{result['sent']:.0f} draws recorded", result["cpu_us"], None, "us",
                   "1 kHz, every draw", every and result["cpu_us"] < 1000.0)  # fmt: skip


def measures(size: Size = Size.FULL, seconds: float = 10.0) -> list[Measure]:
    with tempfile.TemporaryDirectory() as folder:
        rows = [calls_measure(size, Path(folder))]
        if size.every_row:
            rows.append(live_measure(live(size.pick(full=seconds, quick=seconds, smoke=0.5), Path(folder))))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--quick", action="store_true", help="only the in-process ratio")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        rows = [calls_measure(Size.QUICK if args.quick else Size.FULL, Path(folder))]
        if not args.quick:
            result = live(args.seconds, Path(folder))
            print(result)
            rows.append(live_measure(result))
    print_measures(rows)


if __name__ == "__main__":
    main()
