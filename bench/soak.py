"""Soak and fault suite: the bridge for a long run, and through its peers crashing.

Run: .venv/bin/python bench/soak.py [--minutes 10] [--only soak|faults]

1. Soak. The bridge as a process on its built-in default config; an LCM publisher sends a
   100-link scene (a load every minute, draws at 1 kHz); rclpy subscribers with reliable QoS
   take the per-draw outputs (`/drake/poses`, `/tf`) raw. Every minute: messages sent,
   received by the bridge, published, delivered to the subscribers, dropped (by cause: conflated
   by the route's `latest` policy, or dropped by the kernel before the bridge read them), errors,
   and the bridge's RSS. Goals: 0 errors, RSS growth < 5 MB after the first minute (warm-up).
2. Faults, each with the time to recover measured from the peer's return (goal: < 1 s, no
   manual step):
   - the LCM publisher killed and restarted (draws only: the bridge keeps its model);
   - the bridge killed with SIGKILL and restarted with `load_cache` (the model is back, and
     re-posed markers flow, before any new load);
   - the ROS subscriber restarted (it gets the latched model at once);
   - the ign peer (Debian's ign-transport CLI) restarted;
   - a Director viewer restarted (its tree is gone: MISSING_PATHS, the bridge's client resends);
   - the render server's client disconnecting mid-upload (the next request is served).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
from common import flat_stats

from viewer_bridge.config.bridge import DEFAULT_CONFIG
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.model.scene import Box, Geometry, Link, LinkPoses, Pose, Scene
from viewer_bridge.transports.lcm import LcmBus

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(120 + os.getpid() % 40))
URL = f"udpm://239.255.76.67:{8100 + os.getpid() % 100}?ttl=0"
IGN_CLI = "/usr/libexec/ignition/transport11/ign-transport-topic"
LINKS = 100


def scene(links: int = LINKS) -> Scene:
    return Scene(
        tuple(
            Link(f"plant::robot::link_{i}", 1, (Geometry(Box((0.1, 0.1, 0.1)), Pose((0.05, 0, 0))),))
            for i in range(links)
        )
    )


def draw(names: tuple[str, ...], sequence: int, epoch: int) -> LinkPoses:
    """A draw that says who sent it: link 0 at x = sequence (exact in float32), y = epoch."""
    positions = np.zeros((len(names), 3))
    positions[:, 2] = np.arange(len(names))
    positions[0, :2] = sequence % 2**24, epoch
    quaternions = np.tile([1.0, 0.0, 0.0, 0.0], (len(names), 1))
    return LinkPoses(sequence, names, np.ones(len(names), np.int32), positions, quaternions)


# --- the peers ------------------------------------------------------------------------------------


class Bridge:
    """`viewer-bridge run` as a process, with its stats file, RSS and log."""

    def __init__(self, folder: Path, config: str = "builtin:default", *args: str) -> None:
        self.stats = folder / f"stats-{time.monotonic_ns()}.json"
        command = [sys.executable, "-m", "viewer_bridge.cli.main", "run", "-c", config, "--lcm-url", URL,
                   "--set", "foxglove.port=0", "--stats-json", str(self.stats), "--stats-period", "1", *args]  # fmt: skip
        self.process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True)
        self.lines: list[str] = []
        self.running = threading.Event()
        threading.Thread(target=self._read, daemon=True).start()
        if not self.running.wait(60):
            raise RuntimeError("the bridge did not start:\n" + "\n".join(self.lines))
        self.up_at = time.monotonic()

    def _read(self) -> None:
        assert self.process.stderr is not None
        for line in self.process.stderr:
            self.lines.append(line.rstrip())
            if " running (" in line:
                self.running.set()

    def snapshot(self) -> dict[str, Any]:
        try:
            return flat_stats(json.loads(self.stats.read_text()))
        except (OSError, ValueError):
            return {}

    def rss_mb(self) -> float:
        for line in Path(f"/proc/{self.process.pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
        return float("nan")

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            self.process.wait(timeout=20)

    def kill(self) -> None:
        self.process.kill()
        self.process.wait()


class Publisher:
    """Drake's side: a load, then draws at `rate_hz`, on a thread; `epoch` marks who sent them."""

    def __init__(
        self, rate_hz: float, epoch: int = 1, send_load: bool = True, load_every_s: float = 60.0
    ) -> None:
        self.the_scene = scene()
        self.names = tuple(link.name for link in self.the_scene.links)
        self.bus = LcmBus(URL)
        self.rate_hz, self.epoch, self.load_every_s = rate_hz, epoch, load_every_s
        self.send_load = send_load
        self.sent = 0
        self.loads = 0
        self.first_sent_at: float | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def load(self) -> None:
        self.bus.publish("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(self.the_scene).encode())
        self.loads += 1

    def _run(self) -> None:
        encoder = DrawEncoder()
        period = 1.0 / self.rate_hz
        start = time.perf_counter()
        next_load = start
        sequence = 0
        while not self._stop.is_set():
            now = time.perf_counter()
            if self.send_load and now >= next_load:
                self.load()
                next_load += self.load_every_s
            due = start + sequence * period
            if due > now:
                time.sleep(due - now)
            sequence += 1
            self.bus.publish("DRAKE_VIEWER_DRAW", encoder.encode(draw(self.names, sequence, self.epoch)))
            if self.first_sent_at is None:
                self.first_sent_at = time.monotonic()
            self.sent = sequence

    def kill(self) -> None:
        self._stop.set()
        self._thread.join()
        self.bus.close()


@dataclass
class Topic:
    messages: int = 0
    arrivals: list[tuple[float, bytes]] = field(default_factory=list)  # kept only while `keep`
    keep: bool = False


class RosSubscriber:
    """rclpy, reliable, raw bytes: counts what arrives per topic; subscriptions can be dropped."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node("soak_subscriber", context=self.context)
        self.topics: dict[str, Topic] = {}
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        threading.Thread(target=self.executor.spin, daemon=True).start()

    def subscribe(self, name: str, typename: str, latched: bool = False) -> Any:
        from viewer_bridge.transports.ros2 import message_class, qos_profile

        topic = self.topics[name] = Topic()

        def arrived(data: bytes) -> None:
            topic.messages += 1
            if topic.keep:
                topic.arrivals.append((time.monotonic(), bytes(data)))

        return self.node.create_subscription(
            message_class(typename), name, arrived, qos_profile(100, True, latched), raw=True
        )

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def wait_until(condition: Callable[[], bool], timeout: float = 20.0) -> float | None:
    """Seconds until `condition` held (polled every millisecond), or None at `timeout`."""
    started = time.monotonic()
    while time.monotonic() - started < timeout:
        if condition():
            return time.monotonic() - started
        time.sleep(0.001)
    return None


def discovered(subscriber: RosSubscriber, bridge: Bridge, timeout: float = 20.0) -> None:
    """Until the subscriber sees the bridge's node in the ROS graph (DDS discovery), at most
    `timeout` seconds: then the bridge's publishers, made with its first messages, match at once."""
    wait_until(lambda: bridge.process.poll() is not None or "viewer_bridge" in subscriber.node.get_node_names(),
               timeout)  # fmt: skip


def pose_array_epoch(data: bytes) -> int:
    from viewer_bridge.formats.ros.poses import pose_array_arrays

    return int(pose_array_arrays(data)[2][0, 1])


# --- 1. soak --------------------------------------------------------------------------------------------


def soak(folder: Path, minutes: float, rate_hz: float) -> dict[str, Any]:
    print(f"1. soak: {LINKS}-link draws at {rate_hz:.0f} Hz and a load every minute for {minutes:g} min, "
          "built-in default config, reliable rclpy subscribers on /drake/poses and /tf")  # fmt: skip
    bridge = Bridge(folder)
    subscriber = RosSubscriber()
    subscriber.subscribe("/drake/poses", "geometry_msgs/msg/PoseArray")
    subscriber.subscribe("/tf", "tf2_msgs/msg/TFMessage")
    discovered(subscriber, bridge)
    publisher = Publisher(rate_hz)
    rss_start = bridge.rss_mb()
    rss_warm = rss_start
    print(f"{'min':>4} {'sent':>8} {'bridge in':>9} {'poses out':>9} {'tf out':>8} {'delivered':>9} "
          f"{'conflated':>9} {'kernel':>6} {'errors':>6} {'RSS MB':>7}")  # fmt: skip
    rows = []
    started = time.monotonic()
    for minute in range(1, int(np.ceil(minutes)) + 1):
        time.sleep(max(0.0, started + min(minute, minutes) * 60 - time.monotonic()))
        stats = bridge.snapshot()
        poses, tf = stats.get("poses", {}), stats.get("tf", {})
        errors = sum(
            sum(route.get("errors", {}).values()) for name, route in stats.items() if name != "transports"
        )
        kernel = stats.get("transports", {}).get("lcm", {}).get("errors", {}).get("dropped_by_kernel", 0)
        row = {
            "sent": publisher.sent, "in": poses.get("messages_in", 0), "poses_out": poses.get("messages_out", 0),
            "tf_out": tf.get("messages_out", 0), "delivered": subscriber.topics["/drake/poses"].messages,
            "conflated": poses.get("dropped", 0) + tf.get("dropped", 0), "kernel": kernel, "errors": errors,
            "rss": bridge.rss_mb(),
        }  # fmt: skip
        if minute == 1:
            rss_warm = row["rss"]
        rows.append(row)
        widths = {
            "sent": 8,
            "in": 9,
            "poses_out": 9,
            "tf_out": 8,
            "delivered": 9,
            "conflated": 9,
            "kernel": 6,
        }
        print(f"{minute:>4} " + " ".join(f"{row[key]:>{width}}" for key, width in widths.items())
              + f" {row['errors']:>6} {row['rss']:>7.1f}")  # fmt: skip
    publisher.kill()
    # Until the stats say every draw sent was read or dropped by the kernel, and none waits in a
    # route (the file is written every second), at most 10 s: then the figures are final.
    wait_until(lambda: _drained(bridge.snapshot(), publisher.sent), timeout=10.0)
    final = bridge.snapshot()
    bridge.stop()
    subscriber.close()
    last = rows[-1]
    growth = last["rss"] - rss_warm
    errors = sum(
        sum(route.get("errors", {}).values()) for name, route in final.items() if name != "transports"
    )
    result = {"sent": publisher.sent, "loads": publisher.loads, "received": final.get("poses", {}).get("messages_in", 0),
              "published": final.get("poses", {}).get("messages_out", 0) + final.get("tf", {}).get("messages_out", 0),
              "delivered": subscriber.topics["/drake/poses"].messages + subscriber.topics["/tf"].messages,
              "errors": errors, "dropped_by_kernel": last["kernel"], "rss_start": rss_start, "rss_warm": rss_warm,
              "rss_end": last["rss"], "growth_mb": growth}  # fmt: skip
    print(f"   sent {result['sent']} draws and {result['loads']} loads; the bridge received {result['received']}, "
          f"published {result['published']} (poses + tf), the subscribers got {result['delivered']}; "
          f"errors {errors}; RSS {rss_start:.1f} MB at start, {rss_warm:.1f} after warm-up, {last['rss']:.1f} "
          f"at the end: growth {growth:+.1f} MB (goal < 5, 0 errors) {_verdict(growth < 5 and errors == 0)}")  # fmt: skip
    return result


def _drained(stats: dict[str, Any], sent: int) -> bool:
    poses = stats.get("poses", {})
    kernel = stats.get("transports", {}).get("lcm", {}).get("errors", {}).get("dropped_by_kernel", 0)
    queued = sum(route.get("queued", 0) for name, route in stats.items() if name != "transports")
    return bool(poses) and poses.get("messages_in", 0) + kernel >= sent and queued == 0


# --- 2. faults ------------------------------------------------------------------------------------------


def fault_publisher_restart(folder: Path) -> float | None:
    """Kill the LCM publisher, start a new one that sends draws only: poses and markers resume."""
    bridge = Bridge(folder)
    subscriber = RosSubscriber()
    subscriber.subscribe("/drake/poses", "geometry_msgs/msg/PoseArray")
    subscriber.subscribe("/drake/markers", "visualization_msgs/msg/MarkerArray")
    discovered(subscriber, bridge)
    first = Publisher(200.0, epoch=1)
    wait_until(lambda: subscriber.topics["/drake/markers"].messages > 10)
    first.kill()
    time.sleep(1.0)
    poses, markers = subscriber.topics["/drake/poses"], subscriber.topics["/drake/markers"]
    poses.keep, markers_before = True, markers.messages
    second = Publisher(200.0, epoch=2, send_load=False)  # the peer's return: no load, draws only
    waited = wait_until(lambda: any(pose_array_epoch(data) == 2 for _, data in poses.arrivals[-5:]))
    resumed = wait_until(lambda: markers.messages > markers_before, timeout=5)  # the model was kept
    recovery = None
    if waited is not None and second.first_sent_at is not None:
        arrival = next(at for at, data in poses.arrivals if pose_array_epoch(data) == 2)
        recovery = arrival - second.first_sent_at
    second.kill()
    bridge.stop()
    subscriber.close()
    print(f"   LCM publisher restarted: first draw of the new publisher delivered after "
          f"{_ms(recovery)}; re-posed markers without a new load: {'yes' if resumed is not None else 'NO'}")  # fmt: skip
    return recovery if resumed is not None else None


def fault_bridge_killed(folder: Path) -> float | None:
    """SIGKILL the bridge; restarted with the same load_cache, it has the model before any load."""
    config = folder / "cached.yaml"
    config.write_text(DEFAULT_CONFIG + f"load_cache: {folder / 'load_cache'}\n")
    bridge = Bridge(folder, str(config))
    subscriber = RosSubscriber()
    subscriber.subscribe("/drake/markers", "visualization_msgs/msg/MarkerArray")
    markers = subscriber.topics["/drake/markers"]
    discovered(subscriber, bridge)
    publisher = Publisher(200.0)
    wait_until(lambda: markers.messages > 10)
    bridge.kill()
    publisher.send_load = False  # from here on, draws only: the model must come from the cache
    time.sleep(0.5)
    before = markers.messages
    bridge = Bridge(folder, str(config))
    waited = wait_until(lambda: markers.messages > before)
    recovery = None if waited is None else time.monotonic() - bridge.up_at
    loads = publisher.loads
    publisher.kill()
    bridge.stop()
    subscriber.close()
    print(f"   bridge SIGKILLed, restarted with load_cache: markers again {_ms(recovery)} after it was up, "
          f"with {loads} load(s) sent in all (none since the kill)")  # fmt: skip
    return recovery


def fault_subscriber_restart(folder: Path) -> float | None:
    """A new ROS subscriber gets the latched model (link-frame markers) at once."""
    bridge = Bridge(folder)
    first = RosSubscriber()
    first.subscribe("/drake/link_markers", "visualization_msgs/msg/MarkerArray", latched=True)
    discovered(first, bridge)
    publisher = Publisher(200.0)
    wait_until(lambda: first.topics["/drake/link_markers"].messages > 0)
    first.close()
    time.sleep(1.0)
    second = RosSubscriber()
    subscribed_at = time.monotonic()
    second.subscribe("/drake/link_markers", "visualization_msgs/msg/MarkerArray", latched=True)
    waited = wait_until(lambda: second.topics["/drake/link_markers"].messages > 0)
    recovery = None if waited is None else time.monotonic() - subscribed_at
    publisher.kill()
    bridge.stop()
    second.close()
    print(f"   ROS subscriber restarted: the latched model after {_ms(recovery)}")
    return recovery


def fault_ign_peer_restart(folder: Path) -> float | None:
    """Debian's ign-transport CLI echoing Pose_V, killed and started again."""
    environment = dict(os.environ, IGN_PARTITION=f"soak{os.getpid()}", IGN_IP="127.0.0.1")
    # The bridge inherits them; this process's own environment is as it was afterwards.
    with mock.patch.dict(os.environ, IGN_PARTITION=environment["IGN_PARTITION"], IGN_IP="127.0.0.1"):
        bridge = Bridge(folder, "builtin:ign")
    publisher = Publisher(200.0)

    def echo() -> tuple[subprocess.Popen[bytes], float]:
        started = time.monotonic()
        process = subprocess.Popen([IGN_CLI, "-e", "-t", "/drake/pose_v", "-n", "1"], env=environment,
                                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)  # fmt: skip
        return process, started

    recovery = None
    try:
        first, _ = echo()
        first.wait(timeout=30)
        second, started = echo()  # the peer's return
        output = second.communicate(timeout=30)[0]
        if b"plant::robot::link_0" in output:
            recovery = time.monotonic() - started
    except subprocess.TimeoutExpired:
        pass
    publisher.kill()
    bridge.stop()
    print(f"   ign peer restarted: its first Pose_V after {_ms(recovery)} (the CLI's own start included)")
    return recovery


DIRECTOR_CLIENT = """\
routes:
  - name: to_director
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)|DIRECTOR_TREE_VIEWER_RESPONSE_<drake>"}
    translator: drake_to_tree_viewer
    destination: {transport: lcm, name: "DIRECTOR_TREE_VIEWER_REQUEST_<drake>"}
    rate: {policy: all}
"""
DIRECTOR_VIEWER = """\
routes:
  - name: as_director
    source: {transport: lcm, name: "DIRECTOR_TREE_VIEWER_REQUEST_<([^<>]*)>"}
    translator: tree_viewer_server
    destination: {transport: ros, name: "/director/{1:topic}/markers"}
    rate: {policy: all}
"""


def fault_director_viewer_restart(folder: Path) -> float | None:
    """The viewer (the bridge's tree viewer server, as a process) SIGKILLed and restarted empty."""
    from viewer_bridge.formats.tree_viewer import envelope

    (folder / "client.yaml").write_text(DIRECTOR_CLIENT)
    (folder / "viewer.yaml").write_text(DIRECTOR_VIEWER)
    responses: list[tuple[float, int]] = []
    bus = LcmBus(URL)
    bus.subscribe("DIRECTOR_TREE_VIEWER_RESPONSE_<drake>", lambda channel, data, _: responses.append(
        (time.monotonic(), int(envelope.decode(data)["status"]))))  # fmt: skip
    bus.start()
    client = Bridge(folder, str(folder / "client.yaml"))
    viewer = Bridge(folder, str(folder / "viewer.yaml"))
    publisher = Publisher(100.0)
    wait_until(lambda: any(status == envelope.OK for _, status in responses))
    viewer.kill()
    killed_at = time.monotonic()
    viewer = Bridge(folder, str(folder / "viewer.yaml"))  # its tree is empty: the peer's return

    def since_the_kill() -> list[tuple[float, int]]:
        return [(at, status) for at, status in responses if at >= killed_at]

    def complete_again() -> bool:
        after = [status for _, status in since_the_kill()]
        return envelope.MISSING_PATHS in after and after[-1] == envelope.OK

    recovery = None
    if wait_until(complete_again) is not None:
        after = since_the_kill()
        # Back when it said so, or answered first (its first answers may come before its log line).
        back = min(viewer.up_at, after[0][0])
        missing = next(index for index, (_, status) in enumerate(after) if status == envelope.MISSING_PATHS)
        recovered = next(at for at, status in after[missing:] if status == envelope.OK)
        recovery = max(0.0, recovered - back)
    publisher.kill()
    viewer.stop()
    client.stop()
    bus.close()
    print(
        f"   Director viewer restarted empty: MISSING_PATHS, the client resent, OK again after {_ms(recovery)}"
    )
    return recovery


def fault_render_client_leaves(folder: Path) -> float | None:
    """A render client that disconnects halfway through its upload; the next request is served."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "viewer_bridge.cli.main", "serve-render", "--port", str(port)],
                              stderr=subprocess.DEVNULL)  # fmt: skip
    recovery = None
    try:
        wait_until(lambda: _connects(port), timeout=30)
        body, content_type = _render_form()
        with socket.create_connection(("127.0.0.1", port)) as leaving:
            leaving.sendall(f"POST /render HTTP/1.1\r\nHost: x\r\nContent-Type: {content_type}\r\n"
                            f"Content-Length: {len(body)}\r\n\r\n".encode() + body[: len(body) // 2])  # fmt: skip
        left_at = time.monotonic()
        status = _post(port, body, content_type)
        if status == 200:
            recovery = time.monotonic() - left_at
    finally:
        server.terminate()
        server.wait(timeout=10)
    print(
        f"   render client left mid-upload: the next request rendered {_ms(recovery)} later (render included)"
    )
    return recovery


def _connects(port: int) -> bool:
    try:
        socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
        return True
    except OSError:
        return False


def _render_form() -> tuple[bytes, str]:
    import hashlib

    from viewer_bridge.formats.gltf import write_gltf

    the_scene = Scene(
        (Link("box", 0, (Geometry(Box((1.0, 1.0, 1.0)), Pose((0, 0, -3)), (1 / 255, 0, 0, 1)),)),)
    )
    document = json.loads(write_gltf(the_scene))
    document["cameras"] = [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.01, "zfar": 10}}]
    document["nodes"].append({"camera": 0, "matrix": np.eye(4).reshape(-1).tolist()})
    document["scenes"][0]["nodes"].append(len(document["nodes"]) - 1)
    gltf = json.dumps(document).encode()
    fields = {"scene": gltf, "scene_sha256": hashlib.sha256(gltf).hexdigest().encode(), "image_type": b"color",
              "width": b"64", "height": b"48", "near": b"0.01", "far": b"10", "focal_x": b"56", "focal_y": b"56",
              "center_x": b"31.5", "center_y": b"23.5"}  # fmt: skip
    boundary = "soakboundary"
    body = (
        b"".join(
            f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'.encode()
            + value
            + b"\r\n"
            for name, value in fields.items()
        )
        + f"--{boundary}--\r\n".encode()
    )
    return body, f"multipart/form-data; boundary={boundary}"


def _post(port: int, body: bytes, content_type: str) -> int:
    import urllib.request

    request = urllib.request.Request(f"http://127.0.0.1:{port}/render", data=body, method="POST",
                                     headers={"Content-Type": content_type})  # fmt: skip
    with urllib.request.urlopen(request, timeout=30) as response:
        return int(response.status)


FAULTS: dict[str, Callable[[Path], float | None]] = {
    "LCM publisher restarted": fault_publisher_restart,
    "bridge SIGKILLed, load_cache": fault_bridge_killed,
    "ROS subscriber restarted": fault_subscriber_restart,
    "ign peer restarted": fault_ign_peer_restart,
    "Director viewer restarted": fault_director_viewer_restart,
    "render client left mid-upload": fault_render_client_leaves,
}


def faults(folder: Path) -> dict[str, float | None]:
    print("\n2. faults: time to recover from the peer's return (goal < 1 s, no manual step)")
    results = {}
    for name, fault in FAULTS.items():
        try:
            results[name] = fault(folder)
        except Exception as error:  # one fault's harness failing must not hide the others' figures
            print(f"   {name}: the harness failed: {error!r}")
            results[name] = None
    print(f"\n   {'fault':<32} {'recovered in':>12}  goal < 1 s")
    for name, seconds in results.items():
        verdict = "met" if seconds is not None and seconds < 1.0 else "NOT met"
        print(f"   {name:<32} {_ms(seconds):>12}  {verdict}")
    return results


def _verdict(met: bool) -> str:
    return "met" if met else "NOT met"


def _ms(seconds: float | None) -> str:
    return "never" if seconds is None else f"{seconds * 1e3:.1f} ms"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--minutes", type=float, default=10.0, help="length of the soak")
    parser.add_argument("--rate", type=float, default=1000.0, help="draws per second in the soak")
    parser.add_argument("--only", choices=["soak", "faults"])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        if args.only != "faults":
            soak(Path(folder), args.minutes, args.rate)
        if args.only != "soak":
            faults(Path(folder))


if __name__ == "__main__":
    main()
