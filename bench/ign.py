"""Benchmark: Drake draws -> ign-transport Pose_V, 1000 links at 1 kHz, CPU per message.

Run: .venv/bin/python bench/ign.py [--seconds 10]

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
from draw_codec import frame, seconds_per_call  # noqa: E402
from router import Bridge, publish_at  # noqa: E402

from bridge.formats.drake import DrawEncoder  # noqa: E402
from bridge.translators import TRANSLATORS, LoadCache  # noqa: E402
from bridge.transports.base import Received  # noqa: E402
from bridge.transports.ign import IgnNode  # noqa: E402
from bridge.transports.lcm import LcmBus  # noqa: E402

os.environ.setdefault("IGN_PARTITION", f"bench{os.getpid()}")
os.environ.setdefault("IGN_IP", "127.0.0.1")

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


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args()
    links = 1000
    names = frame(links).names
    translator = TRANSLATORS["drake_to_ign_pose_v"]({}, LoadCache())
    draw = DrawEncoder().encode(frame(links))
    translator.translate(Received("DRAKE_VIEWER_DRAW", draw))
    own = seconds_per_call(lambda: translator.translate(Received("DRAKE_VIEWER_DRAW", draw)), 0.5)

    import router as bench_router

    with tempfile.TemporaryDirectory() as folder:
        bridge = Bridge(CONFIG, Path(folder), core=0)
        received = []
        node = IgnNode()
        node.subscribe(
            "/bench/pose_v", "ignition.msgs.Pose_V", lambda topic, data, us: received.append(len(data))
        )
        node.start()
        bus = LcmBus(bench_router.URL)
        time.sleep(2.0)
        sent: dict[int, int] = {}
        cpu_before = cpu_seconds(bridge.process.pid)
        publisher = threading.Thread(target=publish_at, args=(bus, 1000.0, args.seconds, names, sent))
        publisher.start()
        publisher.join()
        time.sleep(1.0)
        cpu = cpu_seconds(bridge.process.pid) - cpu_before
        stats = bridge.snapshot()["pose_v"]
        bridge.stop()
        node.close()
        bus.close()
    out = stats["messages_out"]
    print(
        f"1000-link draws at 1 kHz for {args.seconds:.0f} s -> Pose_V on ign-transport (bridge pinned to CPU 0)"
    )
    print(f"  draws sent {len(sent)}, bridge in {stats['messages_in']}, out {out}, dropped {stats['dropped']}, "
          f"received by an ign subscriber {len(received)} ({received[0] if received else 0} bytes each)")  # fmt: skip
    print(
        f"  bridge process CPU per Pose_V   {cpu / max(out, 1) * 1e6:8.1f} us  (LCM in, translate, ZMQ out, stats)"
    )
    print(
        f"  translator alone per Pose_V     {own * 1e6:8.1f} us  (draw bytes -> Pose_V bytes, in this process)"
    )
    print(
        f"  translate ms p50/p99 inside the bridge: {stats['translate_ms']['p50']}/{stats['translate_ms']['p99']}"
    )


if __name__ == "__main__":
    main()
