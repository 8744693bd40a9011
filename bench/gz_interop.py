"""Issue 25's interop checks: the bridge against a real gz-transport 13 peer (`gz topic`).

Run (after bench/gz_peer/build.sh, from the repository root):
    .venv/bin/python bench/gz_interop.py [--env ~/.cache/viewer-bridge/gz13/env.sh] [--config builtin:gz]

Not a pytest test and not part of ./dev test: it needs the gz-transport 13 that
bench/gz_peer/build.sh builds from the upstream sources. It starts `viewer-bridge run -c CONFIG`
with GZ_PARTITION and GZ_IP=127.0.0.1 (only the GZ_* names, as a Gazebo Harmonic user has them;
--also-ign-env sets the IGN_* ones too), publishes a pydrake scene of 100+ links through
DrakeVisualizer on LCM (ttl=0), and checks with gz-transport 13's CLI:
  topics          `gz topic -l` lists the bridge's publications (/drake/pose_v, /drake/model_v)
  subscriptions   `gz topic -l` lists its subscription /drake_in/pose_v (SUBSCRIBERS_REQ/REP)
  publisher info  `gz topic -i` shows the bridge's publishers with gz.msgs.* types
  subscriber info `gz topic -i -t /drake_in/pose_v` shows the bridge's gz.msgs.Pose_V subscriber
  echo            `gz topic -e -t /drake/pose_v -n 1` prints one of the draws sent, pose for pose
                  and bit for bit (matched by its stamp)
  publish         `gz topic -p` of a gz.msgs.Pose_V on /drake_in/pose_v arrives on LCM as a draw
  partition       a second bridge with another GZ_PARTITION: each partition sees one publisher,
                  a third sees none
One PASS/FAIL line per check, then a summary; the exit status is 1 if any check failed.
"""

from __future__ import annotations

import argparse
import codecs
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import drake as drake_lcmtypes  # type: ignore[import-untyped]  # noqa: E402
import lcm  # noqa: E402
import numpy as np  # noqa: E402

from tests.conftest import lcm_url  # noqa: E402
from tests.peers import BridgeProcess  # noqa: E402

DEFAULT_ENV = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "viewer-bridge/gz13/env.sh"
DEFAULT_LCM_URL = "udpm://239.255.76.67:7667?ttl=0"
POSE_TOPIC = "/drake/pose_v"
MODEL_TOPIC = "/drake/model_v"
IN_TOPIC = "/drake_in/pose_v"
DRAW_CHANNEL = "DRAKE_VIEWER_DRAW"
# The draw sent with `gz topic -p`, as the README's example: the second pose has no orientation.
PUBLISHED = (
    "header { stamp { sec: 3 nsec: 250000000 } } "
    'pose { name: "plant::arm" position { x: 1 y: 2 z: 3 } orientation { x: 0 y: 0 z: 0.6 w: 0.8 } } '
    'pose { name: "plant::hand" position { x: 1 } }'
)
PUBLISHED_DRAW = (
    3250,
    ["plant::arm", "plant::hand"],
    [[1.0, 2.0, 3.0], [1.0, 0.0, 0.0]],
    [[0.8, 0.0, 0.0, 0.6], [1.0, 0.0, 0.0, 0.0]],
)


# --- the pydrake scene (run as a process of its own: --publish-scene) ----------------------------------


def publish_scene(url: str, links: int, prefix: str, seconds: float) -> None:
    """`links` free bodies (boxes, spheres, cylinders, capsules, ellipsoids) spinning and drifting,
    drawn by a DrakeVisualizer (illustration, unsuffixed channels) on `url` in real time."""
    from pydrake.geometry import (
        Box,
        Capsule,
        Cylinder,
        DrakeVisualizer,
        DrakeVisualizerParams,
        Ellipsoid,
        Sphere,
    )
    from pydrake.lcm import DrakeLcm
    from pydrake.math import RigidTransform, RollPitchYaw
    from pydrake.multibody.math import SpatialVelocity
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.multibody.tree import SpatialInertia
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.001)
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, 0.0])  # drift, do not fall away
    shapes = [
        Box(0.1, 0.2, 0.3),
        Sphere(0.05),
        Cylinder(0.04, 0.3),
        Capsule(0.03, 0.2),
        Ellipsoid(0.1, 0.2, 0.3),
    ]
    per_instance = 20
    bodies = []
    for index in range(links):
        if index % per_instance == 0:
            instance = plant.AddModelInstance(f"{prefix}{index // per_instance}")
        body = plant.AddRigidBody(
            f"body{index % per_instance}", instance, SpatialInertia.SolidSphereWithMass(1.0, 0.1)
        )
        pose = RigidTransform(RollPitchYaw(0.1 * index, 0.2, 0.3), vector(0.0, 0.0, 0.0))
        color = [(index % 10) / 10, 0.5, 0.3, 1.0]
        plant.RegisterVisualGeometry(body, pose, shapes[index % len(shapes)], f"visual{index}", color)
        bodies.append(body)
    plant.Finalize()
    DrakeVisualizer.AddToBuilder(builder, scene_graph, DrakeLcm(url), DrakeVisualizerParams())
    simulator = Simulator(builder.Build())
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    for index, body in enumerate(bodies):
        start = RigidTransform(
            RollPitchYaw(0.0, 0.1 * index, 0.0), vector(0.3 * (index % 20), 0.3 * (index // 20), 0.5)
        )
        plant.SetFreeBodyPose(context, body, start)
        spin = SpatialVelocity(
            w=vector(0.3 + 0.01 * index, 0.2, 0.1), v=vector(0.01, 0.02 * (index % 3), 0.0)
        )
        plant.SetFreeBodySpatialVelocity(context, body, spin)
    simulator.set_target_realtime_rate(1.0)
    simulator.AdvanceTo(seconds)


def vector(*values: float) -> Any:
    """A float array for pydrake (its stubs name `ndarray[float64, ...]`, which no array type matches)."""
    return np.array(values, dtype=float)


# --- processes and peers -------------------------------------------------------------------------------


def load_env(path: Path) -> dict[str, str]:
    """This process's environment with `path` (build.sh's env.sh) sourced into it."""
    if not path.is_file():
        sys.exit(f"{path}: no such env file; build the peer first: bench/gz_peer/build.sh SOURCE_DIR")
    out = subprocess.run(
        ["bash", "-c", 'set -a; source "$1"; env -0', "_", str(path)], check=True, capture_output=True
    ).stdout
    return dict(item.split("=", 1) for item in out.decode().split("\0") if "=" in item)


@dataclass
class Gz:
    """gz-transport 13's CLI in one partition."""

    env: dict[str, str]
    partition: str

    def __call__(self, *args: str, timeout: float = 30.0) -> str:
        env = {**self.env, "GZ_PARTITION": self.partition, "GZ_IP": "127.0.0.1"}
        try:
            result = subprocess.run(
                ["gz", "topic", *args], env=env, capture_output=True, text=True, timeout=timeout
            )
        except subprocess.TimeoutExpired as error:
            out = error.stdout.decode() if isinstance(error.stdout, bytes) else error.stdout or ""
            return out
        return result.stdout + result.stderr


class LcmListener:
    """Every message on an LCM URL, by channel, received by the lcm package in a thread."""

    def __init__(self, url: str) -> None:
        self.bus = lcm.LCM(url)
        self.messages: dict[str, list[bytes]] = {}
        self._lock = threading.Lock()
        self.bus.subscribe(".*", self._keep)
        self._running = True
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _keep(self, channel: str, data: bytes) -> None:
        with self._lock:
            self.messages.setdefault(channel, []).append(data)

    def _spin(self) -> None:
        while self._running:
            self.bus.handle_timeout(100)

    def on(self, pattern: str) -> list[bytes]:
        with self._lock:
            return [
                data
                for channel, items in self.messages.items()
                if re.fullmatch(pattern, channel)
                for data in items
            ]

    def close(self) -> None:
        self._running = False
        self._thread.join(timeout=2)


def until(condition: Callable[[], bool], timeout: float, period: float = 0.1) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(period)
    return condition()


@contextmanager
def scene(url: str, links: int, prefix: str, seconds: float) -> Iterator[subprocess.Popen[bytes]]:
    command = [
        sys.executable,
        __file__,
        "--publish-scene",
        url,
        "--links",
        str(links),
        "--prefix",
        prefix,
        "--seconds",
        str(seconds),
    ]
    process = subprocess.Popen(command, cwd=ROOT)
    try:
        yield process
    finally:
        process.kill()
        process.wait()


@contextmanager
def bridge(config: str, url: str, partition: str, ign_env: bool, extra: list[str]) -> Iterator[BridgeProcess]:
    """The bridge on `config` in one partition, with only the `GZ_*` names set unless `ign_env`."""
    env = {**os.environ, "GZ_PARTITION": partition, "GZ_IP": "127.0.0.1"}
    for name in ("IGN_PARTITION", "IGN_IP"):
        env.pop(name, None)
    if ign_env:
        env.update(IGN_PARTITION=partition, IGN_IP="127.0.0.1")
    running = BridgeProcess("-c", config, "--lcm-url", url, "--stats-period", "2", *extra, env=env)
    try:
        running.wait_for_line(" running (")
        yield running
    finally:
        running.stop()


# --- protobuf text format (what `gz topic -e` prints) ------------------------------------------------------

Text = dict[str, list[Any]]


def parse_text_format(text: str) -> Text:
    """The first message of TextFormat::PrintToString output: field -> values (nested dicts)."""
    root: Text = {}
    stack = [root]
    for raw in text.strip().split("\n\n", 1)[0].splitlines():
        line = raw.strip()
        if line.endswith("{"):
            child: Text = {}
            stack[-1].setdefault(line[:-1].strip(), []).append(child)
            stack.append(child)
        elif line == "}":
            stack.pop()
        elif ":" in line:
            name, value = (part.strip() for part in line.split(":", 1))
            stack[-1].setdefault(name, []).append(_scalar(value))
    return root


def _scalar(value: str) -> Any:
    if value.startswith('"'):
        return codecs.escape_decode(value[1:-1].encode())[0].decode()
    try:
        return float(value)
    except ValueError:
        return value  # an enum


def field(message: Text, *path: str, default: Any = 0.0) -> Any:
    """One singular value down `path` (proto3 leaves out zeros: absent means the default)."""
    value: Any = message
    for name in path:
        if name not in value:
            return default
        value = value[name][0]
    return value


# --- the checks ---------------------------------------------------------------------------------------------


@dataclass
class Result:
    name: str
    ok: bool
    detail: str


def check_topics(gz: Gz) -> Result:
    wanted = {POSE_TOPIC, MODEL_TOPIC}
    listed: set[str] = set()

    def found() -> bool:
        listed.update(gz("-l").split())
        return wanted <= listed

    until(found, 20.0, 0.5)
    missing = wanted - listed
    return Result(
        "topics",
        not missing,
        f"gz topic -l lists {sorted(listed & wanted)}" + (f"; missing {sorted(missing)}" if missing else ""),
    )


def check_subscriptions(gz: Gz) -> Result:
    listed = until(lambda: IN_TOPIC in gz("-l").split(), 10.0, 0.5)
    return Result("subscriptions", listed, f"gz topic -l {'lists' if listed else 'does not list'} {IN_TOPIC}")


def info(gz: Gz, topic: str) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """`gz topic -i`: (publishers, subscribers) as (address, message type)."""
    sections: dict[str, list[tuple[str, str]]] = {"Publishers": [], "Subscribers": []}
    current: list[tuple[str, str]] | None = None
    for line in gz("-i", "-t", topic).splitlines():
        if line.startswith(("Publishers", "Subscribers")):
            current = sections[line.split()[0]]
        elif line.startswith("  ") and current is not None and "," in line:
            address, typename = (part.strip() for part in line.rsplit(",", 1))
            current.append((address, typename))
        else:
            current = None
    return sections["Publishers"], sections["Subscribers"]


def check_publisher_info(gz: Gz) -> Result:
    expected = {POSE_TOPIC: "gz.msgs.Pose_V", MODEL_TOPIC: "gz.msgs.Model_V"}
    seen = {topic: info(gz, topic)[0] for topic in expected}
    ok = all(
        seen[topic] and {t for _, t in seen[topic]} == {typename} for topic, typename in expected.items()
    )
    return Result(
        "publisher info",
        ok,
        "; ".join(f"{topic}: {[t for _, t in pubs] or 'no publishers'}" for topic, pubs in seen.items()),
    )


def check_subscriber_info(gz: Gz) -> Result:
    subscribers: list[tuple[str, str]] = []

    def found() -> bool:
        subscribers[:] = info(gz, IN_TOPIC)[1]
        return bool(subscribers)

    until(found, 10.0, 0.5)
    ok = any(typename == "gz.msgs.Pose_V" for _, typename in subscribers)
    return Result("subscriber info", ok, f"{IN_TOPIC}: {[t for _, t in subscribers] or 'no subscribers'}")


def check_echo(gz: Gz, listener: LcmListener, min_links: int) -> Result:
    text = gz("-e", "-t", POSE_TOPIC, "-n", "1", timeout=20.0)
    message = parse_text_format(text)
    if "pose" not in message:
        return Result(
            "echo",
            False,
            f"gz topic -e -t {POSE_TOPIC} -n 1 printed nothing in 20 s"
            + (f": {text.strip()[:200]!r}" if text.strip() else ""),
        )
    stamp_ms = (
        int(field(message, "header", "stamp", "sec")) * 1000
        + int(field(message, "header", "stamp", "nsec")) // 1_000_000
    )
    draws = [drake_lcmtypes.lcmt_viewer_draw.decode(data) for data in listener.on(DRAW_CHANNEL)]
    sent = [draw for draw in draws if draw.timestamp == stamp_ms]
    if not sent:
        return Result("echo", False, f"no draw sent at {stamp_ms} ms (of {len(draws)} draws)")
    draw = sent[-1]
    poses = message["pose"]
    got = [
        (
            field(p, "name", default=""),
            [field(p, "position", k) for k in "xyz"],
            [field(p, "orientation", k) for k in "wxyz"],
        )
        for p in poses
    ]
    want = [
        (name, list(position), list(quaternion))
        for name, position, quaternion in zip(draw.link_name, draw.position, draw.quaternion, strict=True)
    ]
    wrong = [f"{w[0]}: got {g}" for g, w in zip(got, want, strict=False) if g != w]
    ok = len(got) == len(want) >= min_links and not wrong
    detail = f"{len(got)} poses at {stamp_ms} ms; the draw sent has {len(want)} links"
    if ok:
        detail += ", every name, position and quaternion bit for bit"
    elif wrong:
        detail += f"; {len(wrong)} differ, first {wrong[0]}"
    return Result("echo", ok, detail)


def check_publish(gz: Gz, listener: LcmListener, channels: str) -> Result:
    def arrived() -> bool:
        gz("-t", IN_TOPIC, "-m", "gz.msgs.Pose_V", "-p", PUBLISHED)
        return bool(listener.on(channels))

    if not until(arrived, 30.0, 0.2):
        return Result(
            "publish", False, f"gz topic -p on {IN_TOPIC} (gz.msgs.Pose_V): nothing on LCM {channels} in 30 s"
        )
    draw = drake_lcmtypes.lcmt_viewer_draw.decode(listener.on(channels)[0])
    timestamp, names, positions, quaternions = PUBLISHED_DRAW
    got = (draw.timestamp, list(draw.link_name), [list(p) for p in draw.position])
    close = all(
        abs(a - b) < 1e-6
        for q, r in zip(draw.quaternion, quaternions, strict=True)
        for a, b in zip(q, r, strict=True)
    )
    ok = got == (timestamp, names, positions) and close
    return Result(
        "publish",
        ok,
        f"LCM draw: t={draw.timestamp} ms, {list(draw.link_name)}, "
        f"positions {got[2]}, quaternions (wxyz) {[list(q) for q in draw.quaternion]}",
    )


def check_partition(env: dict[str, str], args: argparse.Namespace, first: str) -> Result:
    second, empty = f"{first}-b", f"{first}-empty"
    with ExitStack() as stack:
        url = lcm_url(1)
        stack.enter_context(bridge(args.config, url, second, args.also_ign_env, args.bridge_arg))
        stack.enter_context(scene(url, 3, "partition_b", 600.0))
        publishers: dict[str, list[str]] = {}

        def separated() -> bool:
            for partition in (first, second, empty):
                publishers[partition] = [a for a, _ in info(Gz(env, partition), POSE_TOPIC)[0]]
            return len(publishers[first]) == len(publishers[second]) == 1

        ok = until(separated, 30.0, 0.5)
        stray = [t for t in Gz(env, empty)("-l").split() if t.startswith("/drake")]
        ok = ok and not publishers[empty] and not stray and publishers[first] != publishers[second]
    return Result(
        "partition",
        ok,
        "publishers of /drake/pose_v by GZ_PARTITION: "
        + ", ".join(f"{p}: {a or 'none'}" for p, a in publishers.items()),
    )


def run_checks(args: argparse.Namespace) -> list[Result]:
    env = load_env(args.env)
    built = args.env.parent / "BUILT"
    if built.is_file():
        print(f"gz peer ({built}):\n" + "".join(f"  {line}\n" for line in built.read_text().splitlines()))
    partition = f"gz-interop-{os.getpid()}"
    gz = Gz(env, partition)
    results: list[Result] = []

    def record(result: Result) -> None:
        results.append(result)
        print(f"{'PASS' if result.ok else 'FAIL'} {result.name}: {result.detail}", flush=True)

    listener = LcmListener(args.lcm_url)
    try:
        with (
            bridge(args.config, args.lcm_url, partition, args.also_ign_env, args.bridge_arg) as first,
            scene(args.lcm_url, args.links, "robot", 600.0),
        ):
            if not until(lambda: bool(listener.on(DRAW_CHANNEL)), 60.0):
                sys.exit("the pydrake scene published no draw in 60 s")
            for check in (check_topics, check_subscriptions, check_publisher_info, check_subscriber_info):
                record(check(gz))
            record(check_echo(gz, listener, min(args.links, 100)))
            record(check_publish(gz, listener, args.from_channel))
            record(check_partition(env, args, partition))  # while the first bridge runs
            if args.verbose or not all(r.ok for r in results):
                print("  bridge log (last lines):\n" + "\n".join(f"    {line}" for line in first.lines[-12:]))
    finally:
        listener.close()
    return results


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--env", type=Path, default=DEFAULT_ENV, help="build.sh's env file (default: %(default)s)"
    )
    parser.add_argument("--config", default="builtin:gz", help="the bridge's config (default: %(default)s)")
    parser.add_argument(
        "--lcm-url", default=DEFAULT_LCM_URL, help="LCM URL of the scene (default: %(default)s)"
    )
    parser.add_argument(
        "--links", type=int, default=120, help="links in the pydrake scene (default: %(default)s)"
    )
    parser.add_argument(
        "--from-channel",
        default="DRAKE_VIEWER_DRAW_FROM_.*",
        help="LCM channel (regex) the /drake_in/pose_v draws arrive on (default: %(default)s)",
    )
    parser.add_argument(
        "--also-ign-env",
        action="store_true",
        help="give the bridges IGN_PARTITION and IGN_IP too (for a bridge that reads only IGN_*)",
    )
    parser.add_argument(
        "--bridge-arg", action="append", default=[], help="one more argument for the bridge (repeatable)"
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="print the bridge's last log lines")
    parser.add_argument("--publish-scene", metavar="URL", help=argparse.SUPPRESS)
    parser.add_argument("--prefix", default="robot", help=argparse.SUPPRESS)
    parser.add_argument("--seconds", type=float, default=600.0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publish_scene:
        publish_scene(args.publish_scene, args.links, args.prefix, args.seconds)
        return
    results = run_checks(args)
    failed = [r.name for r in results if not r.ok]
    print(
        f"\n{len(results) - len(failed)}/{len(results)} checks passed"
        + (f"; failed: {', '.join(failed)}" if failed else "")
    )
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
