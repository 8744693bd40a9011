"""What every transport offers the router: bytes in, bytes out, and nothing of formats.

Bytes, except within one process: a payload may be a `Value` (`viewer_bridge.payload`), and
`hand_over` gives a publisher the value when it takes one (`ValuePublisher`) and the value's
bytes otherwise.

A transport moves payloads named by a channel or topic. The router knows transports only
through `Transport`; which one a route uses is a word in the config, looked up in
`viewer_bridge.transports.registry.TRANSPORTS`. A transport says which message types it can carry
(`carries`), so a config that routes PoseArray CDR over LCM is refused when it loads.

A message received once is one `Received`, handed to every subscription it matches, so a
decoded form of it (`Received.decoded`) is computed once however many routes read it.

A router makes its transports with `Transport.create(settings, shared)`, handing them what the
transports and translators of one router share (`viewer_bridge.shared.Shared`).
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Generic, Protocol, Self, TypeVar, runtime_checkable

from pydantic import BaseModel, ConfigDict

from viewer_bridge.payload import Payload, Value, size_of
from viewer_bridge.shared import Shared

if TYPE_CHECKING:
    from viewer_bridge.errors import BridgeError

# Payload encodings, named as MCAP names message encodings where it has a name for them.
LCM = "lcm"
CDR = "cdr"
PROTOBUF = "protobuf"
JSON = "json"


@dataclass(frozen=True, slots=True)
class Definition:
    """A ROS 2 type's definition that travels with the type, for types no installed package
    describes (an LCM type's mapping): MCAP's `ros2msg` schema text and the RIHS01 hash."""

    ros2msg: str
    rihs01: str


# In a translator's declared outputs: CDR of types whose definitions their instances carry.
CARRIED_DEFINITION = Definition("", "")


@dataclass(frozen=True, slots=True)
class MessageType:
    """A message type on the wire: its full name and how its bytes are encoded.

    `drake.lcmt_viewer_draw` / lcm, `geometry_msgs/msg/PoseArray` / cdr,
    `ignition.msgs.Pose_V` / protobuf. The name `*` stands for any type of that encoding.
    `definition`, when set, is the type's own (a transport needs no installed package to name
    it); it is no part of the type's identity.
    """

    name: str
    encoding: str
    definition: Definition | None = field(default=None, compare=False, repr=False)

    def __str__(self) -> str:
        return f"{self.name} ({self.encoding})"


Decoded = TypeVar("Decoded")


class Received:
    """One message as a transport received it, shared by every route it is offered to.

    `message_type` is the message's own type when the transport knows it per message (a ROS 2
    topic found by a pattern, a Zenoh key, a Foxglove client's channel), else None: the route's
    type. `origin` is the transport's note of who sent it (a Foxglove client), for the transport's
    own answer when the message is refused (`Transport.rejected`).

    `sent_us` is when the sender sent it, by the middleware's own stamp (DDS's source timestamp,
    rmw_zenoh's attachment), where the transport has one: a command's age counts from it, so a
    message that waited in a stalled process is seen as old as it is.

    `decoded(decoder)` runs `decoder(self)` the first time and returns the same result after:
    a draw that the markers and the poses routes both read is decoded once. Routes run on
    threads of their own; two may race to decode the same message, which costs a second
    decode and nothing else (decoders are pure, and a dict store is atomic).
    """

    __slots__ = ("channel", "data", "received_us", "message_type", "origin", "sent_us", "_decoded")

    def __init__(
        self,
        channel: str,
        data: bytes,
        received_us: int | None = None,
        *,
        message_type: MessageType | None = None,
        origin: object = None,
        sent_us: int | None = None,
    ) -> None:
        self.channel = channel
        self.data = data
        self.received_us = time.time_ns() // 1000 if received_us is None else received_us
        self.message_type = message_type
        self.origin = origin
        self.sent_us = sent_us
        self._decoded: dict[object, Any] | None = None  # made on the first decode: most messages have none

    def sent_at_us(self) -> int:
        """When it was sent, by the sender's stamp where there is one and it is not later than
        this process received it (another host's clock may run ahead), else when it was received."""
        sent = self.sent_us
        return sent if sent is not None and sent <= self.received_us else self.received_us

    def decoded(self, decoder: Callable[[Received], Decoded]) -> Decoded:
        decoded = self._decoded
        if decoded is None:
            decoded = self._decoded = {}
        try:
            return decoded[decoder]  # type: ignore[no-any-return]
        except KeyError:
            value = decoded[decoder] = decoder(self)
            return value


Deliver = Callable[[Received], None]  # called on the transport's thread: hand over and return
# A route's express path for one channel (`Transport.offer_express`): called with a message's bytes
# alone, on the transport's thread; True when it carried the message, False when the message must
# take the full path (a `Received` delivered as usual).
Express = Callable[[bytes], bool]
ExpressFor = Callable[[str], Express | None]  # a channel's express path, or None for none now


@dataclass(frozen=True, slots=True)
class Exposure:
    """Who can send a transport the messages a route reads, said at start for the routes that
    command a robot: `who` for the start-up line, `warning` when that reaches past this machine
    (with how to narrow it), else None."""

    who: str
    warning: str | None = None


# The QoS policies a subscription may take from its topic's publishers (`Qos.follow`), named as
# the config's `qos:` keys name them.
RELIABILITY = "reliability"
DURABILITY = "durability"
DEPTH = "depth"


@dataclass(frozen=True, slots=True)
class Qos:
    """What a route asks of a publisher or subscription; transports use what they have of it.

    `follow` names the policies (`reliability`, `durability`, `depth`) a subscription takes from
    its topic's publishers instead (`viewer_bridge.transports.ros_qos`), in a ROS graph; `admits`
    narrows what a source pattern subscribes to in a graph. `told`,
    when set, is called with the bridge's words when a peer's QoS cannot match (a publisher that
    offers less than a subscription asks, a subscriber that asks more than a publisher offers).
    """

    depth: int = 10
    reliable: bool = True
    latched: bool = False  # late subscribers get the last messages (ROS 2 TRANSIENT_LOCAL)
    follow: frozenset[str] = frozenset()
    told: Callable[[str], None] | None = field(default=None, compare=False, repr=False)
    # For a source matched against a graph: whether a name the pattern matched is worth a
    # subscription (a route that writes commands takes only the channels the allow-list names).
    admits: Callable[[str], bool] | None = field(default=None, compare=False, repr=False)


class Publisher(Protocol):
    """Publishes on one name; says how many subscribers it has, or None when it cannot know.

    `unsent` counts what it was given but could not send (a Zenoh session without a router):
    the route's row shows it as not delivered. Publishers that always send keep it at 0.
    """

    unsent: int

    def publish(self, data: bytes) -> None: ...

    def subscriber_count(self) -> int | None: ...


class TransportSettings(BaseModel):
    """Base of a transport's settings: the config section named after the transport."""

    model_config = ConfigDict(extra="forbid")


class Transport(ABC):
    """A message bus the router can read from and publish to.

    Subclasses set `Settings` (their config section) and `encodings` (what they carry), and
    implement the abstract methods. Callbacks run on the transport's own thread(s).
    """

    Settings: ClassVar[type[TransportSettings]] = TransportSettings
    encodings: ClassVar[frozenset[str]]
    # Whether several processes may open this transport with the same settings at once, each with
    # its own view of the same traffic (a multicast bus, a ROS 2 graph): then the routes that use
    # it may run on worker processes (`viewer_bridge.router.workers`). Not a server's port or a file.
    several_processes: ClassVar[bool] = False
    # Whether its CDR sources are ROS 2 topics found in a ROS graph (DDS, rmw_zenoh): where
    # `ros_topics` looks for the topics it carries onto LCM.
    ros_graph: ClassVar[bool] = False
    # Whether its publishers read nothing but the bytes they are given (not the `MessageTime` of
    # the message being published, as a file's log time does): then a route may publish on them
    # from its express path, which skips that store (`viewer_bridge.router.runner`).
    plain_publishers: ClassVar[bool] = False

    def __init__(self, settings: TransportSettings) -> None:
        self.settings = settings

    @classmethod
    def create(cls, settings: TransportSettings, shared: Shared) -> Self:
        """How a router makes this transport: from its settings, with what the router's transports
        share; a transport that uses some of it overrides this (the default takes none of it)."""
        return cls(settings)

    @classmethod
    def carries(cls, message_type: MessageType) -> bool:
        """Whether messages of this type can travel over this transport."""
        return message_type.encoding in cls.encodings

    @classmethod
    def check_source(cls, name: str) -> None:
        """Refuse a source `name` this transport cannot subscribe to (checked at config load).

        Raises:
            InvalidName: `name` cannot be subscribed to; says why.
        """
        return None

    @classmethod
    def check_destination(cls, name: str) -> None:
        """Refuse a destination `name` this transport cannot publish on (checked at config load, on
        the destination template filled in with sample groups).

        Raises:
            InvalidName: `name` cannot be published on; says why.
        """
        return None

    def require(self, message_types: Iterable[MessageType]) -> None:
        """Refuse a type this process cannot send or receive here (called once at start for every
        type the routes use).

        Raises:
            TransportUnavailable: a type whose support is not installed; says what to install.
        """
        return None

    @abstractmethod
    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        """Deliver every message whose channel fully matches the regex `pattern`.

        A message that matches several subscriptions is one `Received` handed to each.
        """

    def offer_express(self, deliver: Deliver, express_for: ExpressFor) -> None:
        """For a channel whose only route is the one `deliver` serves, `express_for(channel)` may
        give that route's express path: a transport that can use one (a live LCM bus, where a
        small message's Python calls are most of its cost) calls it with the bytes alone, and
        delivers as usual when it returns False. Asked again after each message that took the full
        path. Others ignore it (the default)."""
        return None

    @abstractmethod
    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        """A publisher on `name` (made once per name by the router)."""

    def start(self) -> None:
        """Begin delivering (subscriptions are made before)."""
        return None

    def describe(self) -> str:
        """Where it is, for the start-up line."""
        return type(self).__name__

    def exposure(self) -> Exposure:
        """Who can send this transport messages (said at start when routes reading it write commands)."""
        return Exposure(self.describe())

    def rejected(self, message: Received, error: BridgeError) -> None:
        """Told when a route could not translate a message this transport delivered (`error` says
        why; a `Held` too): a transport whose senders expect an answer gives one (the Foxglove
        server's status message to the client that published). Called on the route's thread."""
        return None

    def errors(self) -> Mapping[str, int]:
        """The transport's own error counts (bad frames, refused datagrams), by kind."""
        return {}

    def finished(self) -> bool:
        """True once a source that ends (a replayed log) has delivered everything."""
        return False

    @abstractmethod
    def close(self) -> None:
        """Stop delivering and release everything."""


@runtime_checkable
class Closable(Protocol):
    """A publisher that frees all its transport holds for it when closed (a DDS writer, a Foxglove
    channel), or holds nothing: a route may then let a quiet stream's publishers go and give its
    lane to a new stream (`Route.stream_idle_s`). Publishers that are not keep their lanes."""

    def close(self) -> None: ...


class CallPublisher:
    """A `Publisher` from a function; the count is unknown unless `count` is given."""

    __slots__ = ("publish", "_count", "unsent")

    def __init__(self, publish: Callable[[bytes], None], count: Callable[[], int] | None = None) -> None:
        self.publish = publish
        self._count = count
        self.unsent = 0

    def subscriber_count(self) -> int | None:
        return None if self._count is None else self._count()


class ClosingPublisher(CallPublisher):
    """A `CallPublisher` that is `Closable`: `close` frees what its transport holds for it."""

    __slots__ = ("close",)

    def __init__(
        self,
        publish: Callable[[bytes], None],
        count: Callable[[], int] | None = None,
        close: Callable[[], None] = lambda: None,  # nothing held: nothing to free
    ) -> None:
        super().__init__(publish, count)
        self.close = close


_ValueType = TypeVar("_ValueType", bound=Value)


class ValuePublisher(CallPublisher, Generic[_ValueType]):
    """A publisher that takes values of one type as they are (`publish_value`), for a transport
    in the router's process; bytes it is given (from a publisher wrapping it, or a test) are
    decoded into one first."""

    __slots__ = ("kind", "publish_value")

    def __init__(
        self,
        kind: type[_ValueType],
        publish_value: Callable[[_ValueType], None],
        count: Callable[[], int] | None = None,
    ) -> None:
        super().__init__(lambda data: publish_value(kind.decode(data)), count)
        self.kind = kind
        self.publish_value = publish_value


def hand_over(publisher: Publisher, payload: Payload) -> None:
    """Publish `payload`: a value as it is where the publisher takes its type, else as bytes."""
    if isinstance(payload, Value):
        if isinstance(publisher, ValuePublisher) and isinstance(payload, publisher.kind):
            publisher.publish_value(payload)
            return
        payload = payload.encode()
    publisher.publish(payload)


__all__ = [
    "CARRIED_DEFINITION",
    "CDR",
    "CallPublisher",
    "Closable",
    "ClosingPublisher",
    "DEPTH",
    "DURABILITY",
    "Decoded",
    "Definition",
    "Deliver",
    "Exposure",
    "Express",
    "ExpressFor",
    "JSON",
    "LCM",
    "MessageType",
    "PROTOBUF",
    "Payload",
    "Publisher",
    "Qos",
    "RELIABILITY",
    "Received",
    "Transport",
    "TransportSettings",
    "Value",
    "ValuePublisher",
    "hand_over",
    "size_of",
]
