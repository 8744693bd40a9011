"""ROS 2 as a transport, through real rclpy: one node, raw CDR bytes in and out.

Publishers take CDR bytes (rclpy publishes them as they are) and subscriptions deliver raw
bytes, so nothing here builds or reads a message: the formats do that. A source name that is
a regular expression is matched against the graph once a second and subscribed as topics of
the wanted type appear. rclpy is imported when the transport starts, not when a config that
names it is checked, so the ROS 2 wheels are needed only by bridges that use them.
"""

# rclpy's own annotations are incomplete; its untyped calls are accepted in this module only.
# mypy: disable-error-code="no-untyped-call"
from __future__ import annotations

import contextlib
import importlib
import re
import threading
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from pydantic import field_validator

from viewer_bridge.errors import InvalidName, TransportUnavailable
from viewer_bridge.transports.base import (
    CDR,
    CallPublisher,
    Deliver,
    MessageType,
    Publisher,
    Qos,
    Received,
    Transport,
    TransportSettings,
)
from viewer_bridge.transports.ros_names import namespace_problem, node_name_problem, topic_problem

if TYPE_CHECKING:
    from rclpy.qos import QoSProfile

_PLAIN_TOPIC = re.compile(r"^[A-Za-z0-9_/~{}]+$")
BUILDABLE_INTERFACES = ("tf2_msgs",)  # no wheel on PyPI: `viewer-bridge ros-interfaces install` builds them
INSTALL_HINT = "pip install 'viewer-bridge[ros]' (ROS 2 Jazzy's rclpy wheels)"


def message_class(typename: str) -> Any:
    """The rclpy class of `pkg/msg/Type`."""
    package, _, name = typename.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def qos_profile(depth: int, reliable: bool = True, latched: bool = False) -> QoSProfile:
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class RosSettings(TransportSettings):
    node: str = "viewer_bridge"
    namespace: str = ""  # relative topic names resolve under it; absolute ones (/tf) do not
    use_sim_time: bool = False
    ros_args: list[str] = []  # what follows `--ros-args` on the command line: remaps, -p, ...

    @field_validator("node")
    @classmethod
    def _valid_node_name(cls, node: str) -> str:
        return _valid(node, node_name_problem(node), "node name")

    @field_validator("namespace")
    @classmethod
    def _valid_namespace(cls, namespace: str) -> str:
        return _valid(namespace, namespace_problem(namespace), "namespace")


def _valid(name: str, problem: str | None, what: str) -> str:
    """`name`, or an `InvalidName` saying why it is no valid ROS 2 `what`."""
    if problem is not None:
        raise InvalidName(f"{name!r} is not a valid ROS 2 {what}: {problem}")
    return name


class RosTransport(Transport):
    """One rclpy node in a context of its own, spun by a thread of its own."""

    Settings = RosSettings
    encodings = frozenset({CDR})

    @classmethod
    def check_source(cls, name: str) -> None:
        if _PLAIN_TOPIC.match(name):  # one topic, not a pattern matched against the graph
            _valid(name, topic_problem(name), "topic name")

    @classmethod
    def check_destination(cls, name: str) -> None:
        _valid(name, topic_problem(name), "topic name")
    settings: RosSettings

    def __init__(self, settings: RosSettings) -> None:
        super().__init__(settings)
        try:
            import rclpy
            from rclpy.context import Context
            from rclpy.executors import SingleThreadedExecutor
            from rclpy.node import Node
            from rclpy.parameter import Parameter
        except ImportError as error:
            raise TransportUnavailable(f"the ros transport needs rclpy ({error}): {INSTALL_HINT}") from None
        self._context = Context()
        # Global arguments, as any ROS 2 node takes them: `-r __ns:=/sim1`, `-p use_sim_time:=true`.
        rclpy.init(context=self._context, args=["viewer-bridge", "--ros-args", *settings.ros_args])
        # An override beats the command line: set use_sim_time only when the config asks for it.
        overrides = [Parameter("use_sim_time", Parameter.Type.BOOL, True)] if settings.use_sim_time else []
        self.node = Node(
            settings.node, namespace=settings.namespace, context=self._context, parameter_overrides=overrides
        )
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)
        self._patterns: list[tuple[re.Pattern[str], str, Qos, Deliver]] = []
        self._delivers: dict[str, list[Deliver]] = {}  # topic -> every route reading it
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._spin, name="rclpy", daemon=True)
        self._discovery = self.node.create_timer(1.0, self._discover)

    def require(self, message_types: Iterable[MessageType]) -> None:
        for message_type in message_types:
            try:
                message_class(message_type.name)
            except (ImportError, AttributeError, ValueError):
                package = message_type.name.split("/")[0]
                hint = (
                    f"viewer-bridge ros-interfaces install {package}"
                    if package in BUILDABLE_INTERFACES
                    else f"pip install the ROS 2 Jazzy wheel of {package} (ros-jazzy-{package.replace('_', '-')})"
                )
                raise TransportUnavailable(
                    f"the ROS 2 interface {message_type.name} is not installed in this environment: {hint}"
                ) from None

    def start(self) -> None:
        self._thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        with contextlib.suppress(ExternalShutdownException):
            self._executor.spin()

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        profile = qos_profile(qos.depth, qos.reliable, qos.latched)
        publisher = self.node.create_publisher(message_class(message_type.name), name, profile)
        return CallPublisher(publisher.publish, publisher.get_subscription_count)

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        """Raw bytes of the type from `pattern`: a topic, or a regex matched against the graph."""
        if _PLAIN_TOPIC.match(pattern):
            self._subscribe(pattern, message_type.name, qos, deliver)
        else:
            self._patterns.append((re.compile(pattern), message_type.name, qos, deliver))

    def _subscribe(self, topic: str, typename: str, qos: Qos, deliver: Deliver) -> None:
        with self._lock:
            delivers = self._delivers.get(topic)
            if delivers is not None:  # another route reads it already: share the subscription
                if deliver not in delivers:
                    delivers.append(deliver)
                return
            delivers = self._delivers[topic] = [deliver]

        def on_message(data: bytes) -> None:
            message = Received(topic, bytes(data))
            for each in delivers:
                each(message)

        profile = qos_profile(qos.depth, qos.reliable, qos.latched)
        self.node.create_subscription(message_class(typename), topic, on_message, profile, raw=True)

    def _discover(self) -> None:
        if not self._patterns:
            return
        for topic, types in self.node.get_topic_names_and_types():
            for pattern, typename, qos, deliver in self._patterns:
                if pattern.fullmatch(topic) and typename in types:
                    self._subscribe(topic, typename, qos, deliver)

    def describe(self) -> str:
        return f"ROS 2 node {self.node.get_fully_qualified_name()}"

    def close(self) -> None:
        import rclpy

        self._executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        if self._context.ok():
            rclpy.shutdown(context=self._context)
        if self._thread.is_alive():
            self._thread.join(timeout=2)
