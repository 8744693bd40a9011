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

from viewer_bridge.translators.load_cache import LoadCache
from viewer_bridge.transports.base import MessageType, Received, Shared


class TranslatorOptions(BaseModel):
    """Base of a translator's options: the route's `options:` mapping, unknown keys refused."""

    model_config = ConfigDict(extra="forbid", frozen=True)


@dataclass(frozen=True, slots=True)
class Output:
    """One thing a translator publishes: the name suffix, the message type, and if it is latched."""

    suffix: str
    type: MessageType
    latched: bool = False


Outputs = list[tuple[int, bytes]]  # (index into `outputs`, payload)
Reply = Callable[[str, bytes], None]  # publish on the source's transport: (channel, bytes)


def _no_reply(channel: str, data: bytes) -> None:
    raise OSError(f"this route cannot answer on {channel}")


class Translator:
    """Base of every translator.

    `reads` and `outputs` are class attributes; an instance may narrow them from its options
    (e.g. gz instead of ignition message names) within the same encodings. `reply` publishes
    back on the source's transport (the router sets it when `replies` names a type): how a
    protocol with requests and responses, like the tree viewer's, answers.
    """

    Options: ClassVar[type[TranslatorOptions]] = TranslatorOptions
    reads: tuple[MessageType, ...]
    outputs: tuple[Output, ...]
    replies: ClassVar[MessageType | None] = None

    def __init__(
        self, options: Mapping[str, Any] | TranslatorOptions | None = None, loads: LoadCache | None = None
    ) -> None:
        self.options = (
            options
            if isinstance(options, TranslatorOptions)
            else self.Options.model_validate(dict(options or {}))
        )
        self.loads = LoadCache() if loads is None else loads
        self.reply: Reply = _no_reply
        # What the router's transports and translators share (its known LCM types): the router
        # sets its own, as it sets `reply`; a translator made alone gets one of its own.
        self.shared = Shared()

    def observe(self, message: Received) -> None:
        """Bookkeeping every message gets, translated or not (a lazy route with no subscriber)."""

    def translate(self, message: Received) -> Outputs:
        raise NotImplementedError
