"""ROS 2 as a transport, through real rclpy: one node, raw CDR bytes in and out.

Publishers take CDR bytes (rclpy publishes them as they are) and subscriptions deliver raw
bytes, so nothing here builds or reads a message: the formats do that. A source name that is
a regular expression is matched against the graph once a second and subscribed as topics of
the wanted type appear.
"""

# rclpy's own annotations are incomplete; its untyped calls are accepted in this module only.
# mypy: disable-error-code="no-untyped-call"
from __future__ import annotations

import contextlib
import importlib
import re
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

Callback = Callable[[str, bytes, int], None]  # topic, CDR bytes, receive time in microseconds

_PLAIN_TOPIC = re.compile(r"^[A-Za-z0-9_/~{}]+$")


def message_class(typename: str) -> Any:
    """The rclpy class of `pkg/msg/Type`."""
    package, _, name = typename.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def qos_profile(depth: int, reliable: bool = True, latched: bool = False) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class RosNode:
    """One rclpy node spun by a thread of its own."""

    def __init__(self, name: str = "viewer_bridge", namespace: str = "", use_sim_time: bool = False) -> None:
        self._context = Context()
        rclpy.init(context=self._context)
        overrides = [Parameter("use_sim_time", Parameter.Type.BOOL, use_sim_time)]
        self.node = Node(name, namespace=namespace, context=self._context, parameter_overrides=overrides)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)
        self._pattern_subscriptions: list[tuple[re.Pattern[str], str, QoSProfile, Callback]] = []
        self._subscribed: set[str] = set()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._spin, name="rclpy", daemon=True)
        self._discovery = self.node.create_timer(1.0, self._discover)

    def start(self) -> None:
        self._thread.start()

    def _spin(self) -> None:
        with contextlib.suppress(ExternalShutdownException):
            self._executor.spin()

    def publisher(self, topic: str, typename: str, qos: QoSProfile) -> Callable[[bytes], None]:
        """A function publishing CDR bytes on `topic` as `typename`."""
        publisher = self.node.create_publisher(message_class(typename), topic, qos)
        return publisher.publish

    def subscribe(self, name: str, typename: str, qos: QoSProfile, callback: Callback) -> None:
        """Raw bytes of `typename` from `name`: a topic, or a regex matched against the graph."""
        if _PLAIN_TOPIC.match(name):
            self._subscribe(name, typename, qos, callback)
        else:
            self._pattern_subscriptions.append((re.compile(name), typename, qos, callback))

    def _subscribe(self, topic: str, typename: str, qos: QoSProfile, callback: Callback) -> None:
        with self._lock:
            if topic in self._subscribed:
                return
            self._subscribed.add(topic)
        self.node.create_subscription(
            message_class(typename),
            topic,
            lambda data: callback(topic, bytes(data), time.time_ns() // 1000),  # type: ignore[call-overload]
            qos,
            raw=True,
        )

    def _discover(self) -> None:
        if not self._pattern_subscriptions:
            return
        for topic, types in self.node.get_topic_names_and_types():
            for pattern, typename, qos, callback in self._pattern_subscriptions:
                if pattern.fullmatch(topic) and typename in types:
                    self._subscribe(topic, typename, qos, callback)

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        if self._context.ok():
            rclpy.shutdown(context=self._context)
        if self._thread.is_alive():
            self._thread.join(timeout=2)
