"""rmw_zenoh's names and stamps on the wire, as pure functions: data keys, liveliness tokens, attachments.

The format is rmw_zenoh_cpp's for ROS 2 Jazzy, releases 0.2.4 and later (docs/PROTOCOLS.md
section 10). Everything here builds or parses text and bytes, with no session, so the parsers are
fuzz targets and the builders are checked against hand-written examples. A parser refuses what
it cannot read with a `DecodeError` naming the part and the character (or byte) where it failed.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from functools import cache

from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from viewer_bridge.errors import DecodeError

ADMIN_SPACE = "@ros2_lv"  # every liveliness token starts with it
NODE, PUBLISHER, SUBSCRIBER, SERVICE, CLIENT = "NN", "MP", "MS", "SS", "SC"
ENTITY_KINDS = frozenset({NODE, PUBLISHER, SUBSCRIBER, SERVICE, CLIENT})
_SLASH = "%"  # how a `/` inside one part of a key is written (a key's own `/` separates parts)
_DEFAULT_DEPTH = 42  # rmw_zenoh's default depth: a depth equal to it is left out of the QoS part
_HASH = re.compile(r"RIHS01_[0-9a-f]{64}")
_DDS_TYPE = re.compile(r"([A-Za-z][A-Za-z0-9_]*)::(msg|srv|action)::dds_::([A-Za-z][A-Za-z0-9_]*)_")
_NUMBER = re.compile(r"[0-9]+")


# --- type names and hashes ----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class TopicType:
    """A ROS 2 message type as rmw_zenoh names it: `geometry_msgs/msg/PoseArray`, its DDS name
    `geometry_msgs::msg::dds_::PoseArray_` and its RIHS01 hash."""

    name: str
    dds_name: str
    hash: str


@cache
def _store() -> Typestore:
    return get_typestore(Stores.ROS2_JAZZY)


@cache
def topic_type(name: str) -> TopicType:
    """`pkg/msg/Type` with its hash, computed by rosbags from the type's definition.

    Raises `KeyError` for a type rosbags does not know.
    """
    store = _store()
    if name not in store.fielddefs:
        raise KeyError(name)
    return TopicType(name, dds_type_name(name), store.hash_rihs01(name))


def dds_type_name(name: str) -> str:
    """`geometry_msgs/msg/PoseArray` -> `geometry_msgs::msg::dds_::PoseArray_`."""
    package, kind, type_name = name.split("/")
    return f"{package}::{kind}::dds_::{type_name}_"


def ros_type_name(dds_name: str) -> str | None:
    """`geometry_msgs::msg::dds_::PoseArray_` -> `geometry_msgs/msg/PoseArray`; None for other text."""
    match = _DDS_TYPE.fullmatch(dds_name)
    return f"{match.group(1)}/{match.group(2)}/{match.group(3)}" if match else None


# --- data keys ----------------------------------------------------------------------------------------


def data_key(domain: int, topic: str, topic_type: TopicType) -> str:
    """`<domain>/<topic without its leading slash>/<DDS type name>/<hash>`: where samples go."""
    return f"{domain}/{_strip_slashes(topic)}/{topic_type.dds_name}/{topic_type.hash}"


def _strip_slashes(name: str) -> str:
    """One leading and one trailing `/` taken off, as rmw_zenoh does."""
    return name[1 if name.startswith("/") else 0 : -1 if name.endswith("/") else None]


@dataclass(frozen=True, slots=True)
class DataKey:
    domain: int
    topic: str  # fully qualified: /drake/poses
    dds_type: str
    type_hash: str


def parse_data_key(key: str) -> DataKey:
    """A data key read back; `DecodeError` names the part that does not fit."""
    parts = key.split("/")
    if len(parts) < 4:
        raise _key_error(key, "key", 0, f"{len(parts)} parts, not at least 4 (domain/topic/type/hash)")
    domain, *topic, dds_type, type_hash = parts
    if not _NUMBER.fullmatch(domain):
        raise _key_error(key, "domain", 0, f"{domain!r} is not a domain id")
    if not all(topic):
        raise _key_error(key, "topic", len(domain) + 1, "an empty part")
    type_at = len(key) - len(type_hash) - len(dds_type) - 1
    if ros_type_name(dds_type) is None:
        raise _key_error(key, "type", type_at, f"{dds_type!r} is not a DDS type name (pkg::msg::dds_::Type_)")
    if not _HASH.fullmatch(type_hash):
        raise _key_error(key, "type_hash", len(key) - len(type_hash), f"{type_hash!r} is not an RIHS01 hash")
    return DataKey(int(domain), "/" + "/".join(topic), dds_type, type_hash)


def _key_error(key: str, field: str, offset: int, reason: str) -> DecodeError:
    return DecodeError("rmw_zenoh.data_key", field, offset, f"{reason} in {key!r}", unit="character")


# --- liveliness tokens --------------------------------------------------------------------------------


def mangle(name: str) -> str:
    """A name as one part of a key: `/` becomes `%`, and an empty name is `%`."""
    return name.replace("/", _SLASH) or _SLASH


def demangle(part: str) -> str:
    return part.replace(_SLASH, "/")


@dataclass(frozen=True, slots=True)
class TokenQos:
    """The QoS a token declares: what rmw_zenoh writes of it (deadline, lifespan and liveliness
    are always the defaults here, and are read only to be checked)."""

    reliable: bool = True
    transient_local: bool = False
    keep_all: bool = False
    depth: int = _DEFAULT_DEPTH


def qos_part(qos: TokenQos) -> str:
    """The compact QoS string: `reliability:durability:history,depth:deadline:lifespan:liveliness`,
    each value the rmw enum's number, left empty when it is rmw_zenoh's default (reliable,
    volatile, keep last, depth 42, infinite durations, automatic liveliness)."""
    reliability = "" if qos.reliable else "2"  # RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT
    durability = "1" if qos.transient_local else ""  # RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL
    history = "2" if qos.keep_all else ""  # RMW_QOS_POLICY_HISTORY_KEEP_ALL
    depth = "" if qos.depth == _DEFAULT_DEPTH else str(qos.depth)
    return f"{reliability}:{durability}:{history},{depth}:,:,:,,"


_RELIABILITY = {"": True, "1": True, "2": False}
_DURABILITY = {"": False, "1": True, "2": False}
_HISTORY = {"": False, "1": False, "2": True}
_DURATIONS = ("deadline", "lifespan", "liveliness")  # sec,nsec; sec,nsec; kind,sec,nsec


def parse_qos_part(text: str) -> TokenQos:
    parts = text.split(":")
    if len(parts) != 6:
        raise DecodeError("rmw_zenoh.qos", "qos", 0, f"{len(parts)} parts, not 6, in {text!r}", "character")
    reliability, durability, history, *durations = parts
    history_kind, _, depth = history.partition(",")
    for field, value, known in (
        ("reliability", reliability, _RELIABILITY),
        ("durability", durability, _DURABILITY),
        ("history", history_kind, _HISTORY),
    ):
        if value not in known:
            raise DecodeError(
                "rmw_zenoh.qos", field, 0, f"{value!r} is no {field} policy in {text!r}", "character"
            )
    for field, value, count in (("depth", depth, 1), *zip(_DURATIONS, durations, (2, 2, 3), strict=True)):
        numbers = value.split(",")
        if len(numbers) != count or any(number and not _NUMBER.fullmatch(number) for number in numbers):
            reason = f"{value!r} is not {count} comma-separated numbers (or blanks) in {text!r}"
            raise DecodeError("rmw_zenoh.qos", field, 0, reason, "character")
    return TokenQos(
        _RELIABILITY[reliability],
        _DURABILITY[durability],
        _HISTORY[history_kind],
        int(depth or _DEFAULT_DEPTH),
    )


@dataclass(frozen=True, slots=True)
class NodeName:
    """A node as tokens name it: its namespace (`/` for none), name and security enclave."""

    name: str
    namespace: str = "/"
    enclave: str = "/"


@dataclass(frozen=True, slots=True)
class TopicEntity:
    """What a publisher's or subscriber's token adds to its node's: the topic, its type and QoS."""

    topic: str  # fully qualified
    dds_type: str
    type_hash: str
    qos: TokenQos


@dataclass(frozen=True, slots=True)
class Token:
    """One liveliness token: who declared it (session, node id, entity id), what it is, and for
    publishers, subscribers, services and clients their topic."""

    domain: int
    zid: str
    node_id: int
    entity_id: int
    kind: str
    node: NodeName
    topic: TopicEntity | None = None

    def key(self) -> str:
        parts = [ADMIN_SPACE, str(self.domain), self.zid, str(self.node_id), str(self.entity_id), self.kind,
                 mangle(self.node.enclave), mangle(self.node.namespace), mangle(self.node.name)]  # fmt: skip
        if self.topic is not None:
            topic = self.topic
            parts += [
                mangle(topic.topic),
                mangle(topic.dds_type),
                mangle(topic.type_hash),
                qos_part(topic.qos),
            ]
        return "/".join(parts)


def gid(token_key: str) -> bytes:
    """An entity's 16-byte GID: the XXH3 128-bit hash of its token's key, low half first, each
    half little-endian."""
    import xxhash  # with eclipse-zenoh, in the `zenoh` extra: a config naming the transport loads without it

    return xxhash.xxh3_128_intdigest(token_key.encode()).to_bytes(16, "little")


def parse_token(key: str) -> Token:
    """A liveliness token read back; `DecodeError` names the part that does not fit."""
    parts = key.split("/")
    if len(parts) not in (9, 13):
        raise _token_error(key, "key", 0, f"{len(parts)} parts, not 9 (a node) or 13 (a topic's entity)")
    offsets = [sum(len(part) + 1 for part in parts[:index]) for index in range(len(parts))]
    for index, part in enumerate(parts):
        if not part:
            raise _token_error(key, "key", offsets[index], "an empty part")
    admin, domain, zid, node_id, entity_id, kind, enclave, namespace, name, *topic = parts
    if admin != ADMIN_SPACE:
        raise _token_error(key, "admin_space", 0, f"{admin!r} is not {ADMIN_SPACE}")
    for index, field in ((1, "domain"), (3, "node_id"), (4, "entity_id")):
        if not _NUMBER.fullmatch(parts[index]):
            raise _token_error(key, field, offsets[index], f"{parts[index]!r} is not a number")
    if kind not in ENTITY_KINDS:
        raise _token_error(key, "kind", offsets[5], f"{kind!r} is none of {', '.join(sorted(ENTITY_KINDS))}")
    if (kind == NODE) != (not topic):
        raise _token_error(key, "key", 0, f"a {kind} token with {len(parts)} parts")
    node = NodeName(demangle(name), demangle(namespace), demangle(enclave))
    entity = None
    if topic:
        topic_name, dds_type, type_hash, qos = topic
        try:
            entity = TopicEntity(
                demangle(topic_name), demangle(dds_type), demangle(type_hash), parse_qos_part(qos)
            )
        except DecodeError as error:
            raise _token_error(key, f"qos.{error.field}", offsets[12], error.reason) from None
    return Token(int(domain), zid, int(node_id), int(entity_id), kind, node, entity)


def _token_error(key: str, field: str, offset: int, reason: str) -> DecodeError:
    return DecodeError("rmw_zenoh.liveliness_token", field, offset, f"{reason} in {key!r}", unit="character")


# --- attachments ----------------------------------------------------------------------------------------

ATTACHMENT = struct.Struct("<qqB16s")  # sequence number, source timestamp (ns), GID length 16, GID
ATTACHMENT_SIZE = ATTACHMENT.size  # 33


def attachment(sequence: int, timestamp_ns: int, source_gid: bytes) -> bytes:
    return ATTACHMENT.pack(sequence, timestamp_ns, 16, source_gid)


@dataclass(frozen=True, slots=True)
class Attachment:
    sequence: int
    timestamp_ns: int
    gid: bytes


def parse_attachment(data: bytes) -> Attachment:
    """The 33 bytes every sample carries, read back; `DecodeError` for any other shape."""
    if len(data) != ATTACHMENT_SIZE:
        raise DecodeError(
            "rmw_zenoh.attachment", "attachment", 0, f"{len(data)} bytes, not {ATTACHMENT_SIZE}"
        )
    sequence, timestamp_ns, length, source_gid = ATTACHMENT.unpack(data)
    if length != 16:
        raise DecodeError("rmw_zenoh.attachment", "gid.length", 16, f"{length}, not 16")
    return Attachment(sequence, timestamp_ns, source_gid)


def wildcard(key: str) -> bool:
    """Whether a sample's key expression has a wildcard chunk (`*`, `**`, `$*`). A put on a
    wildcard key reaches every subscriber whose key it covers, past access-control rules written
    for the concrete keys (a rule applies only where its key expression covers the put's): so a
    sample must come on the concrete key it is for, or it is dropped."""
    return "*" in key
