"""What every translator is: the message types it reads and writes, its options, one call per message.

A translator takes one received message and returns the payloads to publish, per output. It
declares its types (`reads`, `outputs`, `replies`) as `MessageType`s, never transports: the
config check matches them against what each route's transports carry. Its options are a
pydantic model that refuses unknown keys, checked when the config loads.

The router makes one translator per route and destination (so the illustration and proximity
streams of one route never share state) and calls `observe` for every message, then
`translate` unless the route is lazy and nobody listens.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict

from viewer_bridge.shared import Shared
from viewer_bridge.translators.load_cache import LoadCache
from viewer_bridge.transports.base import MessageType, Payload, Received


class TranslatorOptions(BaseModel):
    """Base of a translator's options: the route's `options:` mapping, unknown keys refused."""

    model_config = ConfigDict(extra="forbid", frozen=True)


@dataclass(frozen=True, slots=True)
class Output:
    """One thing a translator publishes: the name suffix, the message type, and if it is latched."""

    suffix: str
    type: MessageType
    latched: bool = False


# (index into `outputs`, payload: bytes, or a `Value` for a transport in this process)
Outputs = list[tuple[int, Payload]]
Reply = Callable[[str, bytes], None]  # publish on the source's transport: (channel, bytes)


def _no_reply(channel: str, data: bytes) -> None:
    raise RuntimeError(f"a translator that declares no `replies` answered on {channel}")


class Translator:
    """Base of every translator.

    `reads` and `outputs` are class attributes; an instance may narrow them from its options
    (e.g. gz instead of ignition message names) within the same encodings, and may add outputs
    as it runs (a camera's ports, as its images arrive): `outputs` is what `translate`'s indices
    point into. `writes(options)` declares, before any message, every type a translator with
    those options may publish: the config check and the router's start-up check (is each
    interface installed?) use it, never `outputs`.

    Made as `Translator(options)`, with two keyword arguments the router gives:
    - `shared`: what the translators (and transports) of one router share, given by the router
      (`shared.given(LoadCache)`) or made once per router on first ask (the draw decoders of
      `drake_stream`); a translator made alone gets a `Shared` of its own, its loads in memory.
      Nothing is shared between routers or kept in a module.
    - `reply`: publishes back on the source's transport, `reply(channel, bytes)`: how a protocol
      with requests and responses, like the tree viewer's, answers. Required when the class
      declares `replies`; fixed for the translator's life (never set after it is made).
    A subclass with its own `__init__` takes `*args, **kwargs` and passes them on.

    `commands` marks a translator whose outputs command a robot-facing bus (the generic way back
    to LCM): the router writes only the destinations the config's `commands.allow` names, and
    drops what is older than the route's `max_age_ms` (`viewer_bridge.transports.command_policy`).

    `exclusive` marks a translator each of whose destinations carries one source's stream (a
    ROS 2 topic its own LCM channel): a stream for a destination that another stream of any of
    the router's routes carries is held (`channel_taken`), the first kept.

    `relays` marks a translator whose one output is each message's bytes as they are, and `quick`
    is overridden by one that can make a message's one payload from its bytes alone: the router
    then carries most messages of a quick `policy: all` route on its express path
    (`viewer_bridge.router.runner.RouteRunner.express`), with neither `observe` nor `translate`.

    Raises:
        pydantic.ValidationError: options its `Options` model refuses (a `ValueError`; a config
            names the file and line instead).
        TypeError: a class that declares `replies` made with no `reply=` (a bug in the caller,
            not bad input). Its `reply` raises `RuntimeError` when a class that declares no
            `replies` answers (a bug in the translator).
    """

    Options: ClassVar[type[TranslatorOptions]] = TranslatorOptions
    reads: tuple[MessageType, ...]
    outputs: tuple[Output, ...]
    replies: ClassVar[MessageType | None] = None
    commands: ClassVar[bool] = False
    exclusive: ClassVar[bool] = False
    relays: ClassVar[bool] = False

    def __init__(
        self,
        options: Mapping[str, Any] | TranslatorOptions | None = None,
        *,
        shared: Shared | None = None,
        reply: Reply | None = None,
    ) -> None:
        self.options = (
            options
            if isinstance(options, TranslatorOptions)
            else self.Options.model_validate(dict(options or {}))
        )
        self.shared = Shared(given=[LoadCache()]) if shared is None else shared
        if reply is None and self.replies is not None:
            raise TypeError(f"{type(self).__name__} answers with {self.replies}: give it reply=")
        self.reply: Reply = _no_reply if reply is None else reply

    @classmethod
    def writes(cls, options: TranslatorOptions) -> tuple[MessageType, ...]:
        """Every type a translator with these options may publish (by default, its `outputs`')."""
        return tuple(dict.fromkeys(output.type for output in cls.outputs))

    def quick(self, data: bytes) -> tuple[int, bytes] | None:
        """The one (output index, payload bytes) a message of these bytes makes, with nothing else
        done (no state kept, no part skipped, nothing `observe` would do left undone), or None when
        this message needs `observe` and `translate` (a type not seen yet). Only overridden by a
        translator that can: the base's is never called (the router checks for an override)."""
        return None

    def direct(self) -> tuple[int, Callable[[bytes], bytes | None]] | None:
        """For the express path, while the translator's outputs stay as they are now: an output
        and a function that makes, in one call (no Python frame of its own), that output's payload
        from a message's bytes, or says None for a message it cannot make (then `quick` does); None
        when there is no such function. Only asked of a translator that overrides `quick`."""
        return None

    def observe(self, message: Received) -> None:
        """Bookkeeping every message gets, translated or not (a lazy route with no subscriber)."""

    def translate(self, message: Received) -> Outputs:
        raise NotImplementedError


__all__ = [
    "Output",
    "Outputs",
    "Reply",
    "Translator",
    "TranslatorOptions",
]
