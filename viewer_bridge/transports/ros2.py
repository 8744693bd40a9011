"""ROS 2 as a transport, through real rclpy: one node, raw CDR bytes in and out.

Publishers take CDR bytes (rclpy publishes them as they are) and subscriptions deliver raw
bytes, so nothing here builds or reads a message: the formats do that. rclpy still needs a type's
generated type support to publish it: a type whose interface package is missing, but whose
definitions the router was given (`Shared.ros_definitions`), is built in the background
(`viewer_bridge.ros_build.background`); until it is importable its route's messages are dropped and counted
as `waiting_for_build`, then published. A source name that is a regular expression is matched
against the graph once a second and subscribed as topics of the wanted type appear; a pattern of
type `*` takes each topic whose type is a generated LCM type the router knows, building its
interface if it must, and one of type `**` any topic whose type is installed here but for those
this node publishes on or that has no publisher yet (`viewer_bridge.transports.topic_types`). Every message delivered carries
its topic's type (`Received.message_type`). rclpy is
imported when the transport starts, not when a config that names it is checked, so the ROS 2
wheels are needed only by bridges that use them.
"""

# rclpy's own annotations are incomplete; its untyped calls are accepted in this module only.
# mypy: disable-error-code="no-untyped-call"
from __future__ import annotations

import contextlib
import importlib
import logging
import os
import re
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

from pydantic import Field, field_validator

from viewer_bridge.errors import Held, InvalidName, TransportUnavailable
from viewer_bridge.ros_build.background import BuildState, InterfaceBuilder
from viewer_bridge.shared import Shared
from viewer_bridge.transports.base import (
    CDR,
    ClosingPublisher,
    Deliver,
    Exposure,
    MessageType,
    Publisher,
    Qos,
    Received,
    Transport,
    TransportSettings,
)
from viewer_bridge.transports.fastdds_profile import shared_memory_profile
from viewer_bridge.transports.ros_names import namespace_problem, node_name_problem, topic_problem
from viewer_bridge.transports.ros_qos import (
    DEFAULT_MAX_DEPTH,
    Offered,
    describe,
    followed,
    incompatible_publication,
    incompatible_subscription,
    same_profile,
)
from viewer_bridge.transports.topic_types import EVERY, TopicTypes, found_in_graph
from viewer_bridge.util.extras import missing

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.qos import QoSProfile

log = logging.getLogger("viewer_bridge")

_PLAIN_TOPIC = re.compile(r"[A-Za-z0-9_/~{}]+")  # fullmatch: `$` takes "name\n"
LOCAL_RANGES = ("LOCALHOST", "OFF")  # discovery ranges that reach no other host (but static peers)
BUILDABLE_INTERFACES = ("tf2_msgs",)  # no wheel on PyPI: `viewer-bridge ros-interfaces install` builds them


def discovery_range(environ: Mapping[str, str]) -> tuple[str, str]:
    """How far ROS 2 discovery reaches, as Jazzy reads the environment: the range (unset, empty
    and SYSTEM_DEFAULT are the middleware's default, the subnet; the older ROS_LOCALHOST_ONLY=1
    means LOCALHOST when no range is set) and the static peers, if any."""
    scope = environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper()
    if not scope and environ.get("ROS_LOCALHOST_ONLY", "").strip() == "1":
        scope = "LOCALHOST"
    if scope not in ("LOCALHOST", "OFF", "SUBNET"):
        scope = "SUBNET"
    return scope, environ.get("ROS_STATIC_PEERS", "").strip()


def message_class(typename: str) -> Any:
    """The rclpy class of `pkg/msg/Type`."""
    package, _, name = typename.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


SWITCH_S = 2.0  # a followed subscription is re-made at most this often (a peer whose QoS flaps)
RETIRE_S = 1.0  # a replaced subscription delivers this long beside its successor, duplicates dropped
MAX_SWITCH_KEYS = 65_536  # message keys one switch remembers (about 6 MiB), whatever the rate
GONE_TICKS = 3  # discovery rounds (seconds) a pattern's topic may have no publisher before it is dropped


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
    # Fast DDS: a shared-memory segment of this many MiB for the node's participant, for large
    # messages at high rates, unless the user gave Fast DDS a profile of their own; 0 (the default)
    # leaves Fast DDS's own 512 KiB (see `viewer_bridge.transports.fastdds_profile`).
    shared_memory_mb: int = Field(default=0, ge=0, le=4096)
    # The most messages a subscription that follows its publishers keeps (their largest depth, or
    # for transient local the sum of their depths, bounded by this): `viewer_bridge.transports.ros_qos`.
    max_qos_depth: int = Field(default=DEFAULT_MAX_DEPTH, ge=1, le=10_000)

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


class Switch:
    """While a topic's subscription is being replaced, which messages were delivered already:
    the keys (the writer's timestamp and sequence number) of those the old and the new
    subscription delivered in the meantime, and the writers' time span the earlier subscriptions
    covered, whose messages a transient-local successor receives again as history. Only a
    switch pays for it: outside one, a message costs no key."""

    __slots__ = ("ends", "covered", "_keys")

    def __init__(self, covered: tuple[int, int], ends: float) -> None:
        self.covered, self.ends = covered, ends
        self._keys: set[tuple[int, int]] = set()

    def delivered(self, info: dict[str, Any], history: bool) -> bool:
        """Whether a message (its rclpy message info) was delivered before; `history`: it came
        from the new subscription, whose history repeats what the old one delivered live."""
        sent = info["source_timestamp"]
        key = (sent, info["publication_sequence_number"])
        if key in self._keys:
            return True
        if history and self.covered[0] <= sent < self.covered[1]:
            # The old subscription delivered it live, or still will (it was in flight at the
            # switch): not remembered, so that copy passes.
            return True
        if len(self._keys) < MAX_SWITCH_KEYS:
            self._keys.add(key)
        return False


class TopicSubscription:
    """One topic's subscription, shared by every route that reads it; while its QoS follows the
    publishers (`Qos.follow`), re-made when what they offer calls for another profile.

    The new subscription is made before the old one goes, and the old one delivers for `RETIRE_S`
    beside it, so no message is lost in between; a `Switch` drops the second copy of a message.
    """

    def __init__(
        self,
        node: Node,
        topic: str,
        message_type: MessageType,
        asked: Qos,
        delivers: list[Deliver],
        max_depth: int,
    ) -> None:
        self.node, self.topic, self.message_type, self.asked = node, topic, message_type, asked
        self.delivers, self.max_depth = delivers, max_depth
        self.qos = asked  # what the live subscription asks
        self.from_pattern = False  # made by discovery: dropped once its publishers are gone
        self.quiet_ticks = 0  # discovery rounds in a row without a publisher
        self._live: Any = None
        self._retiring: list[tuple[Any, float]] = []  # (subscription, when it goes)
        self._switched_at = -SWITCH_S
        self._switch: Switch | None = None  # while a switch is under way
        self._since_ns = 0  # when the first subscription was made: what the live ones covered since
        self._message_class: Any = None

    def start(self, message_class: Any) -> None:
        """Subscribe, as the publishers known now call for (the type's class is importable now)."""
        self._message_class = message_class
        self.qos = followed(self.asked, offered_by(self.node, self.topic), self.max_depth)
        self._since_ns = time.time_ns()
        self._live = self._create(self.qos, successor=False)

    def _create(self, qos: Qos, successor: bool) -> Any:
        from rclpy.event_handler import SubscriptionEventCallbacks

        events = SubscriptionEventCallbacks(
            incompatible_qos=self._incompatible, incompatible_type=self._other_type
        )
        profile = qos_profile(qos.depth, qos.reliable, qos.latched)
        # A transient-local successor hears the past again: its history is checked as such.
        on_message = self.message_callback(history=successor and qos.latched)
        return self.node.create_subscription(
            self._message_class,
            self.topic,
            on_message,  # type: ignore[arg-type]  # rclpy passes the message info to a second parameter
            profile,
            event_callbacks=events,
            raw=True,
        )

    def message_callback(self, history: bool) -> Callable[[bytes, dict[str, Any]], None]:
        """rclpy's callback of one subscription: the raw bytes to every route reading the topic,
        stamped with the writer's time; during a switch, a message delivered before is dropped."""

        def on_message(data: bytes, info: dict[str, Any]) -> None:
            switch = self._switch
            if switch is not None and self._repeated(switch, info, history):
                return
            sent_us = info["source_timestamp"] // 1000
            message = Received(self.topic, bytes(data), message_type=self.message_type, sent_us=sent_us)
            for each in self.delivers:
                each(message)

        return on_message

    def _repeated(self, switch: Switch, info: dict[str, Any], history: bool) -> bool:
        if time.monotonic() >= switch.ends:  # the switch is over: back to no keys at all
            self._switch = None
            return False
        return switch.delivered(info, history)

    def refresh(self, publishers: list[Offered] | None = None) -> None:
        """Re-make the subscription when its `publishers` (found now if not given) call for another
        profile (at most once per `SWITCH_S`), and let go of replaced ones whose time is up. On the
        executor's thread."""
        now = time.monotonic()
        for subscription, ends in [*self._retiring]:
            if now >= ends:
                self._retiring.remove((subscription, ends))
                self.node.destroy_subscription(subscription)
        if self._live is None or not self.asked.follow:
            return
        if publishers is None:
            publishers = offered_by(self.node, self.topic)
        wanted = followed(self.asked, publishers, self.max_depth)
        if not publishers or same_profile(wanted, self.qos) or now - self._switched_at < SWITCH_S:
            return
        log.info("viewer-bridge: %s: its publishers offer %s now (was %s): subscribed anew",
                 self.topic, describe(wanted), describe(self.qos))  # fmt: skip
        # What arrives before the new subscription is matched, and its history, is checked
        # against what was delivered for a while after the old one is gone.
        self._switch = Switch((self._since_ns, time.time_ns()), now + RETIRE_S + SWITCH_S)
        replaced, self._live = self._live, self._create(wanted, successor=True)
        self.qos, self._switched_at = wanted, now
        self._retiring.append((replaced, now + RETIRE_S))

    def _incompatible(self, info: Any) -> None:
        from rclpy.qos import QoSPolicyKind

        policy = QoSPolicyKind(info.last_policy_kind).name
        if policy.lower() in self.asked.follow:  # a publisher just found: follow it now
            self.refresh()
        elif self.asked.told is not None:
            publishers = offered_by(self.node, self.topic)
            self.asked.told(incompatible_subscription(self.topic, policy, self.qos, publishers))

    def _other_type(self, info: Any) -> None:
        if self.asked.told is not None:
            self.asked.told(f"{self.topic}: a publisher of another type than {self.message_type.name}: "
                            "its messages are not received")  # fmt: skip

    def close(self) -> None:
        for subscription in [self._live, *(each for each, _ in self._retiring)]:
            if subscription is not None:
                self.node.destroy_subscription(subscription)
        self._live, self._retiring = None, []


def offered_by(node: Node, topic: str) -> list[Offered]:
    """What each publisher on `topic` offers, but this node's own (and a worker's node of its name)."""
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    name, namespace = node.get_name(), node.get_namespace()
    return [
        Offered(
            info.qos_profile.reliability == ReliabilityPolicy.RELIABLE,
            info.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL,
            int(info.qos_profile.depth),
        )
        for info in node.get_publishers_info_by_topic(topic)
        if not (info.node_name == name and info.node_namespace == namespace)
    ]


class PublisherOnceBuilt:
    """A publisher of a type whose interface package is being built: until it is ready, each
    message is held (`Held`: `waiting_for_build`, counted on its channel), or after a failed build
    refused as an error (`TransportUnavailable`, which the builder also said once); the rclpy
    publisher is made once it is ready.

    Dropped rather than queued: a route carries state that its next message supersedes, and a
    message held through a build (tens of seconds) would arrive stale and out of its time.
    """

    def __init__(
        self, node: Node, builder: InterfaceBuilder, topic: str, typename: str, profile: QoSProfile
    ) -> None:
        self._node, self._builder, self._topic, self._typename, self._profile = (
            node,
            builder,
            topic,
            typename,
            profile,
        )
        self._package = typename.split("/")[0]
        self._publisher: Any = None
        self.unsent = 0  # held while building (counted by the route), never given and lost
        self._lock = threading.Lock()
        builder.request(self._package)

    def _ready(self) -> Any:
        """The rclpy publisher, made on the first call after the build, or None before."""
        with self._lock:
            if self._publisher is None and self._builder.status(self._package).state is BuildState.READY:
                self._publisher = self._node.create_publisher(
                    message_class(self._typename), self._topic, self._profile
                )
            return self._publisher

    def publish(self, data: bytes) -> None:
        publisher = self._ready()
        if publisher is None:
            status = self._builder.status(self._package)
            if status.state is BuildState.FAILED:
                raise TransportUnavailable(
                    f"the interface package {self._package} failed to build: {status.reason}"
                )
            raise Held("waiting_for_build", f"{self._package} is being built (its messages wait, counted)")
        publisher.publish(data)

    def subscriber_count(self) -> int:
        publisher = self._ready()
        return 0 if publisher is None else int(publisher.get_subscription_count())


class RosTransport(Transport):
    """One rclpy node in a context of its own, spun by a thread of its own."""

    Settings = RosSettings
    encodings = frozenset({CDR})
    several_processes = True  # a node per process in one graph
    ros_graph = True
    plain_publishers = True

    @classmethod
    def check_source(cls, name: str) -> None:
        if _PLAIN_TOPIC.fullmatch(name):  # one topic, not a pattern matched against the graph
            _valid(name, topic_problem(name), "topic name")

    @classmethod
    def check_destination(cls, name: str) -> None:
        _valid(name, topic_problem(name), "topic name")

    settings: RosSettings

    def __init__(
        self, settings: RosSettings, builder: InterfaceBuilder | None = None, shared: Shared | None = None
    ) -> None:
        super().__init__(settings)
        try:
            import rclpy
            from rclpy.context import Context
            from rclpy.executors import SingleThreadedExecutor
            from rclpy.node import Node
            from rclpy.parameter import Parameter
            from rclpy.signals import SignalHandlerOptions
        except ImportError as error:
            raise missing(error, "the ros transport") from None
        self._context = Context()
        # Global arguments, as any ROS 2 node takes them: `-r __ns:=/sim1`, `-p use_sim_time:=true`.
        # An override beats the command line: set use_sim_time only when the config asks for it.
        overrides = [Parameter("use_sim_time", Parameter.Type.BOOL, True)] if settings.use_sim_time else []
        with shared_memory_profile(settings.shared_memory_mb):  # read as the node makes the participant
            # No signal handlers of rclpy's: the bridge handles Ctrl-C and SIGTERM itself (a
            # worker ignores Ctrl-C, its parent stops it), and rclpy's would raise KeyboardInterrupt.
            rclpy.init(
                context=self._context,
                args=["viewer-bridge", "--ros-args", *settings.ros_args],
                signal_handler_options=SignalHandlerOptions.NO,
            )
            self.node = Node(
                settings.node,
                namespace=settings.namespace,
                context=self._context,
                parameter_overrides=overrides,
            )
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self.node)
        self._patterns: list[tuple[re.Pattern[str], MessageType, Qos, Deliver]] = []
        self._types = TopicTypes(Shared() if shared is None else shared)  # what a `*` pattern takes
        self._topics: dict[str, TopicSubscription] = {}  # topic -> its subscription, every route reading it
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._spin, name="rclpy", daemon=True)
        self._discovery = self.node.create_timer(1.0, self._discover)
        self.builder = builder  # builds the interface packages of types it lacks, or None
        self._unbuilt: list[TopicSubscription] = []  # subscriptions whose type is being built

    @classmethod
    def create(cls, settings: TransportSettings, shared: Shared) -> RosTransport:
        assert isinstance(settings, RosSettings)
        definitions = shared.ros_definitions  # what it may build of the interfaces it lacks
        return cls(settings, None if definitions is None else InterfaceBuilder(definitions), shared)

    def require(self, message_types: Iterable[MessageType]) -> None:
        for message_type in message_types:
            if message_type.definition is not None or found_in_graph(message_type):
                continue  # a type that carries its definition (any LCM type) waits for its build instead
            try:
                message_class(message_type.name)
            except (ImportError, AttributeError, ValueError):
                if self._building(message_type.name):  # started now, waited for by nobody
                    continue
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

    def _building(self, typename: str) -> bool:
        """Whether the package of `typename` (which does not import) is being built, or now asked
        for; False when this transport cannot build it."""
        package = typename.split("/")[0]
        if self.builder is None or not self.builder.knows(package):
            return False
        self.builder.request(package)
        return True

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        profile = qos_profile(qos.depth, qos.reliable, qos.latched)
        try:
            message = message_class(message_type.name)
        except (ImportError, AttributeError):
            if not self._building(message_type.name):
                raise
            assert self.builder is not None
            return PublisherOnceBuilt(self.node, self.builder, name, message_type.name, profile)
        publisher = self.node.create_publisher(message, name, profile, event_callbacks=self._told(name, qos))
        node = self.node

        def close() -> None:  # when its route lets a quiet stream go: the node drops its DDS writer
            node.destroy_publisher(publisher)

        return ClosingPublisher(publisher.publish, publisher.get_subscription_count, close)

    @staticmethod
    def _told(topic: str, qos: Qos) -> Any:
        """A publisher's event callbacks: a subscriber that asks more than it offers is told to the route."""
        from rclpy.event_handler import PublisherEventCallbacks
        from rclpy.qos import QoSPolicyKind

        told = qos.told

        def incompatible(info: Any) -> None:
            if told is not None:
                told(incompatible_publication(topic, QoSPolicyKind(info.last_policy_kind).name, qos))

        return PublisherEventCallbacks(incompatible_qos=incompatible)

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        """Raw bytes of the type from `pattern`: a topic, or a regex matched against the graph."""
        if _PLAIN_TOPIC.fullmatch(pattern) and not found_in_graph(message_type):
            self._subscribe(pattern, message_type, qos, deliver)
        else:  # a regex, or a topic whose type the graph will say
            self._patterns.append((re.compile(pattern), message_type, qos, deliver))

    def _subscribe(
        self, topic: str, message_type: MessageType, qos: Qos, deliver: Deliver, from_pattern: bool = False
    ) -> None:
        with self._lock:
            subscription = self._topics.get(topic)
            if subscription is not None:  # another route reads it already: share the subscription
                if deliver not in subscription.delivers:
                    subscription.delivers.append(deliver)
                return
            subscription = TopicSubscription(
                self.node, topic, message_type, qos, [deliver], self.settings.max_qos_depth
            )
            subscription.from_pattern = from_pattern
            self._topics[topic] = subscription
        try:
            message = message_class(message_type.name)
        except (ImportError, AttributeError):
            if not self._building(message_type.name):
                with self._lock:
                    del self._topics[topic]
                raise
            with self._lock:  # subscribed once built (`_discover` looks each second)
                self._unbuilt.append(subscription)
            return
        subscription.start(message)

    def _subscribe_built(self) -> None:
        """Make the subscriptions whose type was being built, now that it is ready."""
        assert self.builder is not None
        with self._lock:
            unbuilt, self._unbuilt = self._unbuilt, []
        for subscription in unbuilt:
            typename = subscription.message_type.name
            if self.builder.status(typename.split("/")[0]).state is BuildState.READY:
                subscription.start(message_class(typename))
            else:  # building, or failed (the builder said so once): nothing arrives on it
                with self._lock:
                    self._unbuilt.append(subscription)

    def _discover(self) -> None:
        if self._unbuilt:
            self._subscribe_built()
        self._follow_publishers()
        if not self._patterns:
            return
        for topic, types in self.node.get_topic_names_and_types():
            for pattern, wanted, qos, deliver in self._patterns:
                if not pattern.fullmatch(topic) or (qos.admits is not None and not qos.admits(topic)):
                    continue  # a topic no route would carry (a command channel not allowed) costs nothing
                if wanted.name == EVERY and not self._others_publish(topic):
                    continue
                if (found := self._types.pick(wanted, topic, types)) is None:
                    continue
                try:
                    self._subscribe(topic, found, qos, deliver, from_pattern=True)
                except (ImportError, AttributeError, ValueError):  # `**`: a type not installed here
                    self._types.say(topic, found.name, "whose interface package is not installed here")

    def _follow_publishers(self) -> None:
        """Once a second: each subscription that follows its publishers takes what they offer now,
        and one that a pattern made goes once its topic has had no publisher for `GONE_TICKS`."""
        with self._lock:
            subscriptions = list(self._topics.values())
        for subscription in subscriptions:
            publishers = offered_by(self.node, subscription.topic)
            if subscription.from_pattern and not publishers:
                subscription.quiet_ticks += 1
                if subscription.quiet_ticks >= GONE_TICKS:
                    with self._lock:
                        self._topics.pop(subscription.topic, None)
                    subscription.close()
                continue
            subscription.quiet_ticks = 0
            subscription.refresh(publishers)

    def _others_publish(self, topic: str) -> bool:
        """Whether `topic` has publishers, none of them this node (nor a worker's node of the same
        name): a topic known only by its subscribers may be one the bridge is about to publish."""
        name, namespace = self.node.get_name(), self.node.get_namespace()
        publishers = self.node.get_publishers_info_by_topic(topic)
        return bool(publishers) and not any(
            info.node_name == name and info.node_namespace == namespace for info in publishers
        )

    def describe(self) -> str:
        return f"ROS 2 node {self.node.get_fully_qualified_name()}"

    def exposure(self) -> Exposure:
        scope, peers = discovery_range(os.environ)
        who = f"ROS 2 (DDS, discovery {scope}{f', static peers {peers}' if peers else ''})"
        if scope in LOCAL_RANGES and not peers:
            return Exposure(who)
        reach = f"the static peers {peers}" if scope in LOCAL_RANGES else "any host on the subnet"
        return Exposure(who, (
            f"commands are taken over DDS with discovery {scope}: {reach} can publish on their topics and "
            "command those LCM channels. Keep it to this machine with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, "
            "name the hosts that may with ROS_STATIC_PEERS, or authenticate peers with SROS2 (needs a ROS install)"
        ))  # fmt: skip

    def close(self) -> None:
        import rclpy

        self._executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        if self._context.ok():
            rclpy.shutdown(context=self._context)
        if self._thread.is_alive():
            self._thread.join(timeout=2)
