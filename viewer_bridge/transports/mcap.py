"""An MCAP file as a transport: write-only, each name a route publishes on is a channel of the file.

Two profiles (`mcap: {profile: ...}`, what `viewer-bridge convert --schema` chooses):

* `ros2`: CDR messages, each topic with the `ros2msg` schema rosbags generates for its type
  (what ROS 2 tools and Foxglove read), topic names rooted with `/` as a node in the root
  namespace names them, written by the foxglove-sdk's MCAP writer from a context of its own;
* `foxglove`: Foxglove's protobuf messages (SceneUpdate, FrameTransforms), written by the
  foxglove-sdk's own MCAP writer from the router's one Foxglove context: where the config also
  runs the Foxglove server, the server and the file get every message logged to either
  (viewer_bridge/transports/foxglove.py).

In both, a CDR type that carries its definition (any LCM type's ROS 2 mapping) is written with
that definition as its `ros2msg` schema.

Channels and schemas are registered as topics appear. Each message's log time is the bridge's
clock (the config's `time:`): by default the receive time of the message it was translated from
(`MessageTime`): the log's time when `convert` feeds the router a log, the bus's receive time
live; with `time: sim`, Drake's sim time (the newest draw's, `Clock`). So a route whose destination is this transport
records a live session, and `convert` is a router whose routes all end here.
The file is written as `PATH.partial` and renamed to `PATH` when the transport closes, as every
writer does.
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import Literal, Protocol

from rosbags.typesys import Stores, get_typestore

from viewer_bridge.errors import InvalidName, TransportUnavailable
from viewer_bridge.shared import Clock, MessageTime, Shared
from viewer_bridge.transports.base import (
    CDR,
    PROTOBUF,
    CallPublisher,
    Deliver,
    MessageType,
    Publisher,
    Qos,
    Transport,
    TransportSettings,
)
from viewer_bridge.transports.foxglove import FoxgloveContext, carried, require_schemas
from viewer_bridge.util.extras import missing
from viewer_bridge.util.partial import finish, partial_path

try:
    import foxglove
    from foxglove.mcap import MCAPWriteOptions
except ImportError as error:
    raise missing(error, "the mcap transport (viewer-bridge convert)") from None

Profile = Literal["ros2", "foxglove"]


class McapSettings(TransportSettings):
    path: Path  # the file written
    profile: Profile = "ros2"  # ros2: CDR with ros2msg schemas; foxglove: Foxglove's protobuf messages
    overwrite: bool = False  # replace the file if it exists (otherwise refused at start)


class _File(Protocol):
    """One profile's file: what it holds, its channels, the messages written per topic."""

    messages: Counter[str]

    def require(self, message_types: Iterable[MessageType]) -> None: ...

    def publisher(
        self, topic: str, message_type: MessageType, time: MessageTime, clock: Clock
    ) -> Publisher: ...

    def close(self) -> None: ...


def _logging(channel: foxglove.Channel, topic: str, lock: threading.Lock, messages: Counter[str],
             time: MessageTime, clock: Clock) -> Publisher:  # fmt: skip
    """A publisher logging each message on `channel` at the bridge's log time, counted per topic
    under `lock` (the SDK's log is thread-safe; the counts are not)."""

    def write(data: bytes) -> None:
        with lock:
            messages[topic] += 1
        channel.log(data, log_time=clock.log_time_ns(time.received_us))

    return CallPublisher(write)


class _Ros2File:
    """ROS 2 CDR messages through the foxglove-sdk's MCAP writer (the one writer of the package:
    bench/mcap_files.py measures it against the mcap library's), from a context of its own so
    that no Foxglove server of the router sees these channels."""

    def __init__(self, path: Path) -> None:
        self._context = foxglove.Context()
        options = MCAPWriteOptions(profile="ros2")
        self._writer = foxglove.open_mcap(
            path, allow_overwrite=True, context=self._context, writer_options=options
        )
        self._store = get_typestore(Stores.ROS2_JAZZY)
        self._channels: dict[tuple[str, str], foxglove.Channel] = {}  # by topic and type
        self._lock = threading.Lock()  # for the channels and counts: the SDK's log is thread-safe
        self.messages: Counter[str] = Counter()

    @staticmethod
    def carries(message_type: MessageType) -> bool:
        return message_type.encoding == CDR

    def require(self, message_types: Iterable[MessageType]) -> None:
        for message_type in message_types:
            if message_type.definition is None and message_type.name not in self._store.fielddefs:
                raise TransportUnavailable(f"rosbags has no ROS 2 message definition of {message_type.name}")

    def publisher(self, topic: str, message_type: MessageType, time: MessageTime, clock: Clock) -> Publisher:
        topic = topic if topic.startswith("/") else f"/{topic}"  # as a node in the root namespace names it
        with self._lock:
            channel = self._channel(topic, message_type)
        return _logging(channel, topic, self._lock, self.messages, time, clock)

    def _channel(self, topic: str, message_type: MessageType) -> foxglove.Channel:
        typename = message_type.name
        if (topic, typename) not in self._channels:  # a topic of any LCM type may change type
            definition = message_type.definition
            text = (
                self._store.generate_msgdef(typename, ros_version=2)[0]
                if definition is None
                else definition.ros2msg
            )
            schema = foxglove.Schema(name=typename, encoding="ros2msg", data=text.encode())
            self._channels[(topic, typename)] = foxglove.Channel(
                topic, schema=schema, message_encoding=CDR, context=self._context
            )
        return self._channels[(topic, typename)]

    def close(self) -> None:
        self._writer.close()


class _FoxgloveFile:
    """Foxglove protobuf messages through the foxglove-sdk's MCAP writer, a sink of `context`."""

    def __init__(self, path: Path, context: FoxgloveContext) -> None:
        self._context = context
        self._writer = foxglove.open_mcap(path, allow_overwrite=True, context=context.context)
        self._lock = threading.Lock()  # for the counts: the SDK's log is thread-safe
        self.messages: Counter[str] = Counter()

    @staticmethod
    def carries(message_type: MessageType) -> bool:
        return carried(message_type)

    def require(self, message_types: Iterable[MessageType]) -> None:
        require_schemas(message_types)

    def publisher(self, topic: str, message_type: MessageType, time: MessageTime, clock: Clock) -> Publisher:
        channel = self._context.channel(topic, message_type, "mcap")
        return _logging(channel, topic, self._lock, self.messages, time, clock)

    def close(self) -> None:
        self._writer.close()


_PROFILES: dict[Profile, type[_Ros2File] | type[_FoxgloveFile]] = {
    "ros2": _Ros2File,
    "foxglove": _FoxgloveFile,
}


class McapTransport(Transport):
    """An MCAP file of one profile; publish only."""

    Settings = McapSettings
    encodings = frozenset({CDR, PROTOBUF})
    settings: McapSettings

    def __init__(
        self,
        settings: McapSettings,
        context: FoxgloveContext | None = None,
        time: MessageTime | None = None,
        clock: Clock | None = None,
    ) -> None:
        super().__init__(settings)
        self._clock = Clock() if clock is None else clock
        if settings.path.exists() and not settings.overwrite:
            raise TransportUnavailable(
                f"{settings.path} exists (mcap.path): give another file, or mcap.overwrite: true to replace it"
            )
        self._time = MessageTime() if time is None else time
        # Written as PATH.partial, renamed when closed: a file under its name is whole (util/partial.py).
        self._partial = partial_path(settings.path)
        self.file: _File
        if settings.profile == "ros2":
            self.file = _Ros2File(self._partial)
        else:
            self.file = _FoxgloveFile(self._partial, FoxgloveContext() if context is None else context)

    @classmethod
    def create(cls, settings: TransportSettings, shared: Shared) -> McapTransport:
        assert isinstance(settings, McapSettings)
        # The Foxglove server of this router, if any, logs to the same context (made only when used).
        context = shared.get(FoxgloveContext) if settings.profile == "foxglove" else None
        return cls(settings, context, shared.message_time, shared.clock)

    @classmethod
    def carries(cls, message_type: MessageType, profile: Profile | None = None) -> bool:
        """Whether a file of `profile` (of either profile, when None) holds messages of this type."""
        profiles = _PROFILES.values() if profile is None else (_PROFILES[profile],)
        return any(file.carries(message_type) for file in profiles)

    @classmethod
    def check_source(cls, name: str) -> None:
        raise InvalidName("the mcap transport only writes a file; it cannot be a route's source")

    def require(self, message_types: Iterable[MessageType]) -> None:
        message_types = list(message_types)
        profile = self.settings.profile
        for message_type in message_types:
            if not self.carries(message_type, profile):
                raise TransportUnavailable(
                    f"an MCAP file of the {profile} profile (mcap.profile) cannot hold {message_type}"
                )
        self.file.require(message_types)

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        raise TransportUnavailable("the mcap transport only writes a file")

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        return self.file.publisher(name, message_type, self._time, self._clock)

    @property
    def messages(self) -> Counter[str]:
        """Messages written per topic."""
        return self.file.messages

    def describe(self) -> str:
        return f"MCAP file {self.settings.path} ({self.settings.profile})"

    def close(self) -> None:
        self.file.close()
        if self._partial != self.settings.path:  # a live session's (convert renames its own)
            finish(self._partial, self.settings.path, sum(self.messages.values()))
