"""The typed errors viewer-bridge raises at its edges, all of them here, under `BridgeError`.

Every error names what was wrong and where, so that the router can count it by kind and log one
useful line, and so that a user reading a message knows which field of which type to look at.
The command line catches `BridgeError` once: whatever subclass, one line and exit status 2; any
other exception is a bug, and `--debug` shows its traceback.
"""

from __future__ import annotations

import difflib
from pathlib import Path


class BridgeError(Exception):
    """Base of every error viewer-bridge raises on purpose."""


class SchemaError(BridgeError):
    """An `.lcm` schema file could not be parsed or resolved."""

    def __init__(self, path: str, line: int, reason: str) -> None:
        self.path = path
        self.line = line
        self.reason = reason
        super().__init__(f"{path}:{line}: {reason}" if line else f"{path}: {reason}")  # line 0: not a file


class DecodeError(BridgeError):
    """Bytes (or text inside a message) that do not form a valid message.

    `type_name` is the fully qualified message type, `field` the path of the offending field
    (e.g. `link[2].geom[0].float_data`), `offset` where the problem was found, counted in
    `unit`: bytes of the buffer, elements of an array field, or characters of an embedded JSON.
    """

    def __init__(self, type_name: str, field: str, offset: int, reason: str, unit: str = "byte") -> None:
        self.type_name = type_name
        self.field = field
        self.offset = offset
        self.reason = reason
        self.unit = unit
        super().__init__(f"{type_name}.{field} at {unit} {offset}: {reason}")

    def within(self, type_name: str, prefix: str) -> DecodeError:
        """This error, raised in a nested struct, as seen from the outer type at field `prefix`."""
        return DecodeError(type_name, f"{prefix}.{self.field}", self.offset, self.reason, self.unit)


class JsonValueError(DecodeError):
    """A JSON value (already parsed) that is no message of its type: `field` is the path of the
    offending value in the message's own names (`joint_position[3]`, `pose.position.x`), "" for
    the value as a whole."""

    def __init__(self, type_name: str, field: str, reason: str) -> None:
        super().__init__(type_name, field, 0, reason, unit="JSON value")
        self.args = (f"{type_name}.{field}: {reason}" if field else f"{type_name}: {reason}",)

    def within(self, type_name: str, prefix: str) -> JsonValueError:
        """This error, raised in a nested message, as seen from the outer type at field `prefix`."""
        return JsonValueError(type_name, f"{prefix}.{self.field}" if self.field else prefix, self.reason)


class EncodeError(BridgeError):
    """A message whose content cannot be encoded (wrong length, out-of-range value, ...)."""

    def __init__(self, type_name: str, field: str, reason: str) -> None:
        self.type_name = type_name
        self.field = field
        self.reason = reason
        super().__init__(f"{type_name}.{field}: {reason}")

    def within(self, type_name: str, prefix: str) -> EncodeError:
        """This error, raised in a nested struct, as seen from the outer type at field `prefix`."""
        return EncodeError(type_name, f"{prefix}.{self.field}", self.reason)


class InflateError(BridgeError, ValueError):
    """A zlib stream (a compressed image) that is no zlib stream, ends early, has bytes after it,
    or expands past the size it was given."""


class ShapeDataError(BridgeError):
    """A geometry's shape data that makes no shape, raised inside the load decoder and turned there
    into a `DecodeError` with the field's path: `offset` in `unit`s into `field`."""

    def __init__(
        self, reason: str, offset: int = 0, unit: str = "element", field: str = "float_data"
    ) -> None:
        super().__init__(reason)
        self.reason = reason
        self.offset = offset
        self.unit = unit
        self.field = field


class NoLayout(BridgeError):
    """A message holding something a kept layout does not take; the layout code falls back to the
    general path when it meets one, so it never reaches a caller."""


class SceneError(BridgeError):
    """A scene that a target format cannot express, or a message that makes no valid scene."""


class ConfigError(BridgeError):
    """A configuration or mapping-table file that is not valid: names the file, line and key."""

    def __init__(self, path: str, line: int | None, key: str, reason: str) -> None:
        self.path = path
        self.line = line
        self.key = key
        self.reason = reason
        where = f"{path}:{line}" if line is not None else path
        super().__init__(f"{where}: {key}: {reason}" if key else f"{where}: {reason}")


_LISTED_NAMES = 60  # more known names than this (a type store's hundreds) are counted, not listed


class UnknownName(BridgeError, KeyError):
    """A name no registry knows (a transport, a translator, a type store's type): names the
    closest known one, and the known ones when they are few enough to read. (A `KeyError` too,
    as a lookup by an unknown key is.)"""

    def __init__(self, kind: str, name: str, known: list[str]) -> None:
        self.kind = kind
        self.name = name
        self.known = known
        close = difflib.get_close_matches(name, known, n=1)
        hint = f"did you mean {close[0]!r}? " if close else ""
        listed = f"known: {', '.join(known)}" if len(known) <= _LISTED_NAMES else f"{len(known)} known"
        super().__init__(f"unknown {kind} {name!r} ({hint}{listed})")

    __str__ = BaseException.__str__  # the message as written: KeyError's own would quote it


class NameRefused(BridgeError, ValueError):
    """An LCM name with no valid ROS 2 form (a field, constant, package or type); the message
    names it."""


class NotGiven(BridgeError, LookupError):
    """What a router's `Shared` was asked for and not given when it was made (`Shared.given`)."""


class PluginError(BridgeError):
    """An installed plugin's entry point that is not what its group needs (not a `Transport`...)."""


class InvalidName(BridgeError, ValueError):
    """A channel, topic or key name a transport cannot subscribe to or publish on, or a node or
    namespace name it cannot take; says why. (A `ValueError` too, so that the settings models'
    validators may raise it.)"""


class InvalidSetting(BridgeError, ValueError):
    """A setting's value that cannot be used as given (a pattern that is no regular expression,
    an origin, a Zenoh endpoint or key Zenoh refuses, options that contradict each other); says
    why. (A `ValueError` too, so that the settings models' validators may raise it: the config
    then names the file, line and key.)"""


# Files and documents others wrote.


class LogError(BridgeError):
    """A file that is not an LCM log."""


class CutShort(BridgeError):
    """A bag's storage file that ends before its last record does."""


class GltfError(BridgeError):
    """A glTF document that cannot be read; the message names the part."""


# Director's tree viewer: a request it answers with an error status.


class RequestRejected(BridgeError):
    """A request the tree viewer cannot handle; `status` is the response code that says why:
    -1 unknown format, -2 unknown version, -3 a request it cannot handle, -4 an unknown command."""

    def __init__(self, status: int, reason: str) -> None:
        super().__init__(reason)
        self.status = status


# Transports and what they need on this machine.


class TransportUnavailable(BridgeError):
    """A transport that cannot start here (a missing package, a port in use); says what to do."""


class MissingExtra(BridgeError):
    """An optional dependency that is not installed; names the extra to install it with."""

    def __init__(self, needed_by: str, module: str, extra: str) -> None:
        self.needed_by = needed_by
        self.module = module
        self.extra = extra
        super().__init__(f"{needed_by} needs {module}, not installed: pip install 'viewer-bridge[{extra}]'")


class Held(BridgeError):
    """A message held back on purpose, not broken: its type is unknown here (`unknown_type`),
    cannot be said in the target (`refused_type`), or its interface is still being built
    (`waiting_for_build`). The router counts it per channel and kind, logs the first of each
    once, and goes on; raised by a translator (`observe`, `translate`) or a publisher."""

    def __init__(self, kind: str, reason: str) -> None:
        self.kind = kind
        self.reason = reason
        super().__init__(reason)


class NotAnLcmType(BridgeError):
    """A message routed to LCM whose type is no generated LCM type (or that came with no type):
    names the topic and the type, so the sender (a ROS node, a Foxglove client) can tell."""


class HandshakeError(BridgeError):
    """A client connection whose opening handshake cannot be relayed (cut off, too long, too slow)."""


class FrameLimitError(BridgeError):
    """A client's WebSocket stream past what its frames may cost (one message in too many
    fragments): the connection is let go."""


class HttpRefusal(BridgeError):
    """A connection a server of the bridge answers with an HTTP error `status` instead of serving
    it (403: a browser page of a foreign origin; 503: too many clients at once), counted as `kind`;
    the text names what was refused and the setting that would let it in."""

    def __init__(self, status: int, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.status = status
        self.kind = kind


class BadRequest(BridgeError):
    """A render request the glTF render server refuses with 400 and this text."""


class RosInterfaceError(BridgeError):
    """An interface package could not be built or installed; says which step and why."""


# The command line.


class UsageError(BridgeError):
    """A command line that cannot be run as given: reported as one line, exit status 2."""


class ConvertError(BridgeError):
    """A conversion that cannot start: the output would overwrite something, or nothing would be written."""


class DamagedChunk(BridgeError):
    """A bag's chunk whose records cannot be trusted (it inflates past the size it declares, does
    not decompress, or fails its CRC): it is skipped, and the records around it still read."""


class SummaryTooLarge(BridgeError):
    """An MCAP file whose summary section (its index: schemas, channels, statistics, chunk indexes)
    is larger than the reader holds in memory: the summary is not read, the file's messages are,
    from its records."""


class Interrupted(BridgeError):
    """A conversion stopped midway; `path` (`OUT.partial`) is a valid file of `messages` messages,
    or, when none was written yet, removed (util/partial.py)."""

    def __init__(self, messages: int, path: Path) -> None:
        self.messages = messages
        self.path = path
        kept = (
            f"{messages} messages written to {path}" if messages else "no message written yet: nothing kept"
        )
        super().__init__(f"interrupted: {kept}")


__all__ = [
    "BadRequest",
    "BridgeError",
    "ConfigError",
    "ConvertError",
    "CutShort",
    "DamagedChunk",
    "DecodeError",
    "EncodeError",
    "GltfError",
    "FrameLimitError",
    "HandshakeError",
    "Held",
    "HttpRefusal",
    "InflateError",
    "Interrupted",
    "InvalidName",
    "InvalidSetting",
    "JsonValueError",
    "LogError",
    "MissingExtra",
    "NameRefused",
    "NoLayout",
    "NotAnLcmType",
    "NotGiven",
    "PluginError",
    "RequestRejected",
    "RosInterfaceError",
    "SceneError",
    "SchemaError",
    "ShapeDataError",
    "SummaryTooLarge",
    "TransportUnavailable",
    "UnknownName",
    "UsageError",
]
