"""An example viewer-bridge plugin: an in-memory transport and a translator, nothing else.

`MemoryTransport` is a bus inside one process, named by its settings (`memory: {bus: NAME}`):
`inject` delivers a message as if it had been received, and `published` records what routes
sent. `DrakeDrawToJson` turns Drake's draw into JSON text, using the bridge's shared draw
decoding (so it costs nothing more when another route reads the same draw).
"""

from __future__ import annotations

import json
import re
import threading
from typing import ClassVar

from viewer_bridge.translators.base import Output, Outputs, TranslatorOptions
from viewer_bridge.translators.drake_stream import DrawReader
from viewer_bridge.translators.types import DRAW_TYPE
from viewer_bridge.transports.base import (
    JSON,
    CallPublisher,
    Deliver,
    MessageType,
    Publisher,
    Qos,
    Received,
    Transport,
    TransportSettings,
)


class MemorySettings(TransportSettings):
    bus: str = "default"


class MemoryTransport(Transport):
    """A bus in this process; carries every type, since nothing leaves memory."""

    Settings = MemorySettings
    encodings = frozenset()
    buses: ClassVar[dict[str, MemoryTransport]] = {}

    def __init__(self, settings: MemorySettings) -> None:
        super().__init__(settings)
        self.subscriptions: list[tuple[re.Pattern[str], Deliver]] = []
        self.published: list[tuple[str, str, bytes]] = []  # (name, type, payload)
        self.sent = threading.Condition()
        MemoryTransport.buses[settings.bus] = self

    @classmethod
    def carries(cls, message_type: MessageType) -> bool:
        return True

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        self.subscriptions.append((re.compile(pattern), deliver))

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        def publish(data: bytes) -> None:
            with self.sent:
                self.published.append((name, message_type.name, data))
                self.sent.notify_all()

        return CallPublisher(publish, lambda: 1)

    def inject(self, channel: str, data: bytes) -> None:
        message = Received(channel, data)
        for pattern, deliver in self.subscriptions:
            if pattern.fullmatch(channel):
                deliver(message)

    def wait_for(self, count: int, timeout: float = 60.0) -> list[tuple[str, str, bytes]]:
        with self.sent:
            self.sent.wait_for(lambda: len(self.published) >= count, timeout)
            return list(self.published)

    def close(self) -> None:
        MemoryTransport.buses.pop(self.settings.bus, None)  # type: ignore[attr-defined]


class JsonOptions(TranslatorOptions):
    digits: int = 6


class DrakeDrawToJson(DrawReader):
    """lcmt_viewer_draw -> {"timestamp_ms": T, "links": {name: [x, y, z, qw, qx, qy, qz]}}."""

    Options = JsonOptions
    options: JsonOptions
    reads = (DRAW_TYPE,)
    outputs = (Output("", MessageType("viewer_bridge_example/DrawJson", JSON)),)

    def translate(self, message: Received) -> Outputs:
        poses = self.draw_poses(message)
        links = {
            name: [round(float(value), self.options.digits) for value in (*position, *quaternion)]
            for name, position, quaternion in zip(
                poses.names, poses.positions, poses.quaternions_wxyz, strict=True
            )
        }
        return [(0, json.dumps({"timestamp_ms": poses.timestamp_ms, "links": links}).encode())]
