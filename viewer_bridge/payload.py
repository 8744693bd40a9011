"""What a translator hands the router for one output: bytes, or a `Value`.

Bytes, except within one process: a payload may be a `Value`, the encoded message as an object,
for an encoding whose transport takes the object itself (Rerun's chunks, which its SDK takes as
they are: no serialising them only to parse them back). `viewer_bridge.transports.base.hand_over`
gives a publisher the value when it takes one and the value's bytes otherwise, so a value still
reaches a file, a log or another process as bytes. Here, below the formats and the transports,
because a format defines its values and a transport takes them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Self


class Value(ABC):
    """An encoded message as an object, handed as it is to a transport in the router's process
    that takes it, and as its bytes (`encode`) anywhere else; `decode` reads those bytes back.
    `size` is about how many bytes of data it holds (what a route's `bytes_out` counts)."""

    __slots__ = ()

    @abstractmethod
    def encode(self) -> bytes: ...

    @classmethod
    @abstractmethod
    def decode(cls, data: bytes) -> Self:
        """The value `data` encodes; a `BridgeError` (`DecodeError`) when it is malformed."""

    @property
    @abstractmethod
    def size(self) -> int: ...


Payload = bytes | Value  # what a translator gives the router for one output


def size_of(payload: Payload) -> int:
    """About how many bytes `payload` holds (a value's data, without encoding it)."""
    return payload.size if isinstance(payload, Value) else len(payload)
