"""Real peers for the router's tests: an rclpy node in this process, and the bridge as a process.

Traffic stays on this machine: ROS 2 discovery is limited to localhost with a domain of this test
process's own (set in conftest before rclpy loads), LCM uses a private multicast port.
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from viewer_bridge.transports.ros2 import message_class


def wait_for(condition: Callable[[], bool], timeout: float = 60.0) -> bool:
    """Whether `condition()` came true within `timeout` seconds (checked every 50 ms)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


def qos(depth: int = 100, latched: bool = False) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class RosProbe:
    """An rclpy node of the test's own that records what arrives on topics and can publish."""

    def __init__(self, name: str = "probe") -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.received: dict[str, list[Any]] = {}
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self.executor.spin, daemon=True)
        self._thread.start()

    def subscribe(self, topic: str, typename: str, depth: int = 100, latched: bool = False) -> list[Any]:
        messages: list[Any] = []
        self.received[topic] = messages

        def keep(message: Any) -> None:
            with self._lock:
                messages.append(message)

        self.node.create_subscription(message_class(typename), topic, keep, qos(depth, latched))
        return messages

    def publisher(self, topic: str, typename: str, profile: QoSProfile | None = None) -> Any:
        return self.node.create_publisher(message_class(typename), topic, profile or qos())

    def wait_for(self, condition: Callable[[], bool], timeout: float = 60.0) -> bool:
        return wait_for(condition, timeout)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1)
        # Its spin ends with its current wait: the node is destroyed after, never while the
        # executor adds the node's entities to a wait set (rclpy's InvalidHandle on that thread).
        self._thread.join(timeout=30)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


class BridgeProcess:
    """`viewer-bridge run` in a process of its own (in `env`, by default this one's); its log lines
    are collected."""

    stop_s = 15.0  # how long `stop` waits for it to end

    def __init__(
        self,
        *args: str,
        env: Mapping[str, str] | None = None,
        max_files: int | None = None,
        subcommand: str = "run",
    ) -> None:
        """`max_files`: the bridge's open-file limit (RLIMIT_NOFILE, soft and hard), as `ulimit -n`
        sets it; `subcommand`: `run`, or another that runs routes (`play`)."""
        # Never a fixed port: bridges may run side by side, and beside a user's own.
        command = [
            sys.executable,
            "-m",
            "viewer_bridge.cli.main",
            subcommand,
            "--set",
            "foxglove.port=0",
            *args,
        ]

        def limit_files() -> None:
            if max_files is not None:
                resource.setrlimit(resource.RLIMIT_NOFILE, (max_files, max_files))

        # stdout to nowhere: a pipe nobody reads fills (64 KiB) and then blocks the bridge for good.
        # faulthandler on: a bridge that does not stop is asked for its threads' stacks (`stop`).
        self.process = subprocess.Popen(
            command,
            stderr=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            text=True,
            env={**(os.environ if env is None else env), "PYTHONFAULTHANDLER": "1"},
            preexec_fn=limit_files if max_files is not None else None,
        )
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stderr is not None
        for line in self.process.stderr:
            self.lines.append(line.rstrip())

    def wait_for_line(self, text: str, timeout: float = 60.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.lines):
                if text in line:
                    return line
            if self.process.poll() is not None and not self._reader.is_alive():
                break
            time.sleep(0.05)
        raise AssertionError(f"bridge never logged {text!r}; its log:\n" + "\n".join(self.lines))

    def stop(self) -> int:
        """SIGINT, as Ctrl-C would; returns the exit code. A bridge still running `stop_s` later
        fails the test with its threads' stacks."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            return self.process.wait(timeout=self.stop_s)
        except subprocess.TimeoutExpired:
            raise AssertionError(
                f"the bridge did not stop within {self.stop_s:.0f} s of SIGINT; its log and threads:\n"
                + self._stacks()
            ) from None
        finally:
            self._reader.join(timeout=2)

    def _stacks(self) -> str:
        """The end of the log, with every thread's stack: faulthandler prints them on SIGABRT,
        which ends the process."""
        self.process.send_signal(signal.SIGABRT)
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(timeout=10)
        self._reader.join(timeout=2)
        return "\n".join(self.lines[-120:])


def write_config(folder: Path, text: str) -> Path:
    path = folder / "bridge.yaml"
    path.write_text(text)
    return path
