"""Benchmark: Drake draws -> ign-transport Pose_V, 1000 links at 1 kHz, CPU per message.

Run: .venv/bin/python bench/ign.py [--seconds 10] [--quick]

`measures()` gives issue 15's goal 2 as rows: draw bytes -> Pose_V bytes at 1000 links >= 20x
the protobuf-object path (`pose_v(...).SerializeToString()`, the reference in
tests/formats/ign/oracle.py), and (unless quick) the live run below: 1 kHz x 1000 links carried
by one core.

The bridge (one `drake_to_ign_pose_v` route) runs as a process pinned to CPU 0; this process
publishes 1000-link draws over LCM at 1 kHz and counts the Pose_V messages with an ign-transport
subscriber of its own (on CPU 1). Reported: the bridge process's CPU time per message (from
/proc), beside the translator's own cost per message measured here, in the same run.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from common import Measure, Size, frame  # noqa: E402
from draw_codec import paired, print_measures, seconds_per_call  # noqa: E402
from router import Bridge, publish_at  # noqa: E402

from tests.formats.ign.oracle import pose_v  # noqa: E402
from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder  # noqa: E402
from viewer_bridge.formats.ign.poses import PosesEncoder  # noqa: E402
from viewer_bridge.translators.registry import TRANSLATORS  # noqa: E402
from viewer_bridge.transports.base import Received  # noqa: E402
from viewer_bridge.transports.ign import IgnNode  # noqa: E402
from viewer_bridge.transports.lcm import LcmBus  # noqa: E402

os.environ.setdefault("GZ_PARTITION", f"bench{os.getpid()}")
os.environ.setdefault("GZ_IP", "127.0.0.1")

CONFIG = """\
routes:
  - name: pose_v
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: drake_to_ign_pose_v
    destination: {transport: ign, name: /bench/pose_v}
"""


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def encode_measure(size: Size) -> Measure:
    """draw bytes -> Pose_V bytes (decode included on both sides), ours against the objects."""
    draw = DrawEncoder().encode(frame(1000, seed=1))
    decoder, encoder = DrawDecoder(), PosesEncoder()

    def ours() -> bytes:
        return encoder.encode(decoder.decode(draw))

    def objects() -> bytes:
        return bytes(pose_v(decoder.decode(draw)).SerializeToString())

    assert ours() == objects()  # byte for byte
    fast, slow = paired(ours, objects, size)
    return Measure("draw -> ign Pose_V bytes, 1000 links, vs protobuf objects", fast * 1e6, slow * 1e6, "us",
                   "ratio >= 20x", slow / fast >= 20.0)  # fmt: skip


def live(seconds: float) -> dict[str, float]:
    """The bridge as a process pinned to CPU 0, fed 1000-link draws at 1 kHz for `seconds`."""
    links = 1000
    names = frame(links).names
    import router as bench_router

    with tempfile.TemporaryDirectory() as folder:
        bridge = Bridge(CONFIG, Path(folder), core=0)
        received = []
        node = IgnNode()
        node.subscribe("/bench/pose_v", "gz.msgs.Pose_V", lambda topic, data, us: received.append(len(data)))
        node.start()
        bus = LcmBus(bench_router.URL)
        time.sleep(2.0)
        sent: dict[int, int] = {}
        cpu_before = cpu_seconds(bridge.process.pid)
        publisher = threading.Thread(target=publish_at, args=(bus, 1000.0, seconds, names, sent))
        publisher.start()
        publisher.join()
        time.sleep(1.0)
        cpu = cpu_seconds(bridge.process.pid) - cpu_before
        stats = bridge.snapshot()["pose_v"]
        bridge.stop()
        node.close()
        bus.close()
    out = stats["messages_out"]
    return {
        "sent": len(sent),
        "in": stats["messages_in"],
        "out": out,
        "dropped": stats["dropped"],
        "received": len(received),
        "bytes": received[0] if received else 0,
        "cpu_us": cpu / max(out, 1) * 1e6,
        "p50": stats["translate_ms"]["p50"],
        "p99": stats["translate_ms"]["p99"],
    }


def live_measure(result: dict[str, float]) -> Measure:
    carried = result["out"] >= 0.95 * result["sent"] and result["cpu_us"] < 1000.0
    return Measure("bridge CPU per Pose_V, 1000 links at 1 kHz (one core)", result["cpu_us"], None, "us",
                   "1 kHz carried", carried)  # fmt: skip


def measures(size: Size = Size.FULL, seconds: float = 10.0) -> list[Measure]:
    rows = [encode_measure(size)]
    if size.every_row:
        rows.append(live_measure(live(size.pick(full=seconds, quick=seconds, smoke=0.5))))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--quick", action="store_true", help="only the in-process ratio")
    args = parser.parse_args()
    rows = [encode_measure(Size.QUICK if args.quick else Size.FULL)]
    translator = TRANSLATORS["drake_to_ign_pose_v"]({})
    draw = DrawEncoder().encode(frame(1000))
    translator.translate(Received("DRAKE_VIEWER_DRAW", draw))
    own = seconds_per_call(lambda: translator.translate(Received("DRAKE_VIEWER_DRAW", draw)), 0.5)
    if not args.quick:
        result = live(args.seconds)
        rows.append(live_measure(result))
    print_measures(rows)
    print(
        f"\n  translator alone per Pose_V     {own * 1e6:8.1f} us  (draw bytes -> Pose_V bytes, in this process)"
    )
    if args.quick:
        return
    print(
        f"1000-link draws at 1 kHz for {args.seconds:.0f} s -> Pose_V on ign-transport (bridge pinned to CPU 0)"
    )
    print(f"  draws sent {result['sent']}, bridge in {result['in']}, out {result['out']}, dropped {result['dropped']}, "
          f"received by an ign subscriber {result['received']} ({result['bytes']} bytes each)")  # fmt: skip
    print(
        f"  bridge process CPU per Pose_V   {result['cpu_us']:8.1f} us  (LCM in, translate, ZMQ out, stats)"
    )
    print(f"  translate ms p50/p99 inside the bridge: {result['p50']}/{result['p99']}")


if __name__ == "__main__":
    main()
