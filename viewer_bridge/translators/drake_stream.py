"""Drake's scene as a stream: a load now and then, a draw every frame, shared by every route.

Told apart by the message's fingerprint, not its channel. `LoadCache` (its own module) keeps
the last load per load channel for every route (and, with a folder, across runs). `DrawPoses`
decodes a draw once however many routes read it. Both are per router, got from the router's
`Shared` (`Translator.shared`), never kept in this module. `DrakeStream` is one translator's view: it
says when there is a scene to (re)publish, taking the load from the cache when the route has
not seen it (a late start, a lazy route that was idle when the load came).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.draw import DrawDecoder
from viewer_bridge.formats.drake.load import decode_load
from viewer_bridge.lcmcodec.codecs import DRAW, LOAD_ROBOT
from viewer_bridge.model.lowering import import_trimesh
from viewer_bridge.model.scene import LinkPoses, Scene
from viewer_bridge.shared import Clock
from viewer_bridge.translators.base import Outputs, Translator
from viewer_bridge.translators.load_cache import LoadCache
from viewer_bridge.translators.types import DRAW_TYPE, LOAD_TYPE
from viewer_bridge.transports.base import MessageType, Received

_ROLE = re.compile(r"_(ILLUSTRATION|PROXIMITY|PERCEPTION)\Z")  # \Z: `$` also matches before a final "\n"


def role_of(channel: str) -> str:
    """The role suffix of a Drake viewer channel, lower case: `proximity`; "" when it has none."""
    match = _ROLE.search(channel)
    return match.group(1).lower() if match else ""


def load_channel_for(draw_channel: str) -> str:
    """`DRAKE_VIEWER_DRAW_PROXIMITY` -> `DRAKE_VIEWER_LOAD_ROBOT_PROXIMITY` (same prefix and suffix)."""
    return draw_channel.replace("DRAKE_VIEWER_DRAW", "DRAKE_VIEWER_LOAD_ROBOT", 1)


class DrawPoses:
    """A router's draw decoding (`shared.get(DrawPoses, shared.clock)`): one `DrawDecoder` per
    channel, so each keeps its name block, and each received draw decoded once for every route
    that reads it, which ticks the router's clock (`time: sim`) once per draw."""

    def __init__(self, clock: Clock | None = None) -> None:
        self._clock = Clock() if clock is None else clock
        self._decoders: dict[str, DrawDecoder] = {}
        self._decode_once = self._decode  # one bound method: the key of `Received.decoded`

    def __call__(self, message: Received) -> LinkPoses:
        """A received `lcmt_viewer_draw` as link poses."""
        return message.decoded(self._decode_once)

    def _decode(self, message: Received) -> LinkPoses:
        decoder = self._decoders.get(message.channel)
        if decoder is None:
            decoder = self._decoders.setdefault(message.channel, DrawDecoder())
        poses = decoder.decode(message.data)
        self._clock.tick(poses.timestamp_ms * 1_000_000, message.received_us)
        return poses


def _load_scene(message: Received) -> Scene:
    return decode_load(message.data)


def is_load(message: Received) -> bool:
    return message.data[:8] == LOAD_ROBOT.packed_fingerprint


class DrakeStream:
    """One translator's view of one Drake stream (a load channel and its draw channel), over its
    router's `LoadCache` and `DrawPoses`."""

    def __init__(self, loads: LoadCache, draw_poses: DrawPoses) -> None:
        self.loads = loads
        self.draw_poses = draw_poses
        self.scene: Scene | None = None
        self._load_bytes = b""

    def observe(self, message: Received) -> None:
        """Keep every load in the shared cache, whether this route translates it or not."""
        if is_load(message):
            self.loads.put(message.channel, message.data)

    def read(self, message: Received) -> tuple[Scene | None, LinkPoses | None]:
        """(a scene to publish, or None), (the draw's poses, or None), for one load or draw.

        A load identical to the last one is no new scene. A draw for a scene this translator
        has not published yet (the cache holds a newer load of its channel) brings that scene.
        """
        fingerprint = message.data[:8]
        if fingerprint == LOAD_ROBOT.packed_fingerprint:
            return self._take(message.data, lambda: message.decoded(_load_scene)), None
        if fingerprint == DRAW.packed_fingerprint:
            poses = self.draw_poses(message)
            cached = self.loads.get(load_channel_for(message.channel))
            scene = None
            if cached is not None and cached is not self._load_bytes:
                scene = self._take(cached, lambda: decode_load(cached))
            return scene, poses
        raise DecodeError(
            "drake viewer message", "", 0, f"fingerprint {fingerprint.hex()} is not a load or a draw"
        )

    def _take(self, data: bytes, decode: Callable[[], Scene]) -> Scene | None:
        if data == self._load_bytes:  # re-sent unchanged (e.g. for late listeners): nothing new
            self._load_bytes = data  # the same bytes: compare by identity next time
            return None
        scene = decode()
        self.scene, self._load_bytes = scene, data
        return scene


class DrawReader(Translator):
    """A translator that reads Drake's draws: `self.draw_poses(message)` decodes each once for
    every route of its router."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.draw_poses = self.shared.get(DrawPoses, self.shared.clock)


class DrakeTranslator(DrawReader):
    """A translator of Drake's scene stream (loads and draws): it owns its `DrakeStream`, which
    sees every message, translated or not, so that no load is missed while a route idles."""

    reads: tuple[MessageType, ...] = (LOAD_TYPE, DRAW_TYPE)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.drake = DrakeStream(self.shared.given(LoadCache), self.draw_poses)
        import_trimesh()  # a scene may have meshes: ready before its load comes, not on it

    def observe(self, message: Received) -> None:
        self.drake.observe(message)


class PerLoadTranslator(DrakeTranslator):
    """A translator that publishes once per scene: each new load, and the cached load when a draw
    comes for a scene it has not published (a late start, a lazy route that was idle)."""

    def translate(self, message: Received) -> Outputs:
        scene, _ = self.drake.read(message)
        return [] if scene is None else self.on_scene(scene, message.channel)

    def on_scene(self, scene: Scene, channel: str) -> Outputs:
        raise NotImplementedError
