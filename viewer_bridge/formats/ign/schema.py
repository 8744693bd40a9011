"""The one protobuf schema of ign-msgs 8 / gz-msgs that the bridge speaks, and the names of its types.

`_SCHEMA` below (field numbers from ign-msgs 8, unchanged in gz-msgs 10, see docs/PROTOCOLS.md
sections 4 and 10) is built at import into a protobuf descriptor pool: `MESSAGES`. The wire
format is the `protobuf` package's; only the fields the bridge uses are declared, and a receiver
with the full `.proto` files reads them (unknown fields are skipped both ways). The ign
transport uses it for its discovery datagrams; the format modules beside it for poses, models
and contacts.

The package (`gz.msgs` from Gazebo Garden on, `ignition.msgs` for Fortress and before) is in no
payload byte, only in the type names peers exchange, where a typed subscriber compares it
exactly. So a message is named once, by its short name (`Pose_V`), and `type_name` spells it in
a package: the ign transport with its `package` setting, a route with its own `package` option.

The `Geometry.Type` codes are the geometry table's (`mappings/ign.yaml`): written once, there.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.message import DecodeError as ProtobufDecodeError
from google.protobuf.message import Message

from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.mappings import tables

# name -> fields (name, number, type, repeated). Types are scalar protobuf types or message names.
_SCHEMA: dict[str, list[tuple[str, int, str, bool]]] = {
    "Time": [("sec", 1, "int64", False), ("nsec", 2, "int32", False)],
    "Header": [("stamp", 1, "Time", False), ("data", 2, "Header.Map", True)],
    "Header.Map": [("key", 1, "string", False), ("value", 2, "string", True)],  # nested in Header
    "Vector3d": [("header", 1, "Header", False), ("x", 2, "double", False), ("y", 3, "double", False),
                 ("z", 4, "double", False)],
    "Vector2d": [("header", 1, "Header", False), ("x", 2, "double", False), ("y", 3, "double", False)],
    "Quaternion": [("header", 1, "Header", False), ("x", 2, "double", False), ("y", 3, "double", False),
                   ("z", 4, "double", False), ("w", 5, "double", False)],
    "Pose": [("header", 1, "Header", False), ("name", 2, "string", False), ("id", 3, "uint32", False),
             ("position", 4, "Vector3d", False), ("orientation", 5, "Quaternion", False)],
    "Pose_V": [("header", 1, "Header", False), ("pose", 2, "Pose", True)],
    # Removed from gz-msgs in 2017 but still read by older tools: header, sim time, poses.
    "PosesStamped": [("header", 1, "Header", False), ("time", 2, "Time", False), ("pose", 3, "Pose", True)],
    "Color": [("header", 1, "Header", False), ("r", 2, "float", False), ("g", 3, "float", False),
              ("b", 4, "float", False), ("a", 5, "float", False)],
    "Material": [("header", 1, "Header", False), ("ambient", 5, "Color", False), ("diffuse", 6, "Color", False)],
    "BoxGeom": [("header", 1, "Header", False), ("size", 2, "Vector3d", False)],
    "SphereGeom": [("header", 1, "Header", False), ("radius", 2, "double", False)],
    "CylinderGeom": [("header", 1, "Header", False), ("radius", 2, "double", False), ("length", 3, "double", False)],
    "CapsuleGeom": [("header", 1, "Header", False), ("radius", 2, "double", False), ("length", 3, "double", False)],
    "EllipsoidGeom": [("header", 1, "Header", False), ("radii", 2, "Vector3d", False)],
    "PlaneGeom": [("header", 1, "Header", False), ("normal", 2, "Vector3d", False), ("size", 3, "Vector2d", False),
                  ("d", 4, "double", False)],
    "MeshGeom": [("header", 1, "Header", False), ("filename", 2, "string", False), ("scale", 3, "Vector3d", False)],
    "Geometry": [("header", 1, "Header", False), ("type", 2, "Geometry.Type", False), ("box", 3, "BoxGeom", False),
                 ("cylinder", 4, "CylinderGeom", False), ("plane", 5, "PlaneGeom", False),
                 ("sphere", 6, "SphereGeom", False), ("mesh", 9, "MeshGeom", False),
                 ("capsule", 13, "CapsuleGeom", False), ("ellipsoid", 14, "EllipsoidGeom", False),
                 ("points", 11, "Vector3d", True)],
    "Visual": [("header", 1, "Header", False), ("name", 2, "string", False), ("id", 3, "uint32", False),
               ("parent_name", 4, "string", False), ("pose", 9, "Pose", False), ("geometry", 10, "Geometry", False),
               ("material", 11, "Material", False)],
    "Link": [("header", 1, "Header", False), ("id", 2, "uint32", False), ("name", 3, "string", False),
             ("pose", 10, "Pose", False), ("visual", 11, "Visual", True)],
    "Model": [("header", 1, "Header", False), ("name", 2, "string", False), ("id", 3, "uint32", False),
              ("pose", 5, "Pose", False), ("link", 7, "Link", True), ("visual", 9, "Visual", True)],
    "Model_V": [("header", 1, "Header", False), ("models", 2, "Model", True)],
    # Contacts (ignition/msgs/contacts.proto, contact.proto, entity.proto, joint_wrench.proto, wrench.proto).
    "Entity": [("header", 1, "Header", False), ("id", 2, "uint64", False), ("name", 3, "string", False),
               ("type", 4, "Entity.Type", False)],
    "Wrench": [("header", 1, "Header", False), ("force", 2, "Vector3d", False), ("torque", 3, "Vector3d", False),
               ("force_offset", 4, "Vector3d", False)],
    "JointWrench": [("header", 1, "Header", False), ("body_1_name", 2, "string", False),
                    ("body_1_id", 3, "uint32", False), ("body_2_name", 4, "string", False),
                    ("body_2_id", 5, "uint32", False), ("body_1_wrench", 6, "Wrench", False),
                    ("body_2_wrench", 7, "Wrench", False)],
    "Contact": [("header", 1, "Header", False), ("collision1", 2, "Entity", False),
                ("collision2", 3, "Entity", False), ("position", 4, "Vector3d", True),
                ("normal", 5, "Vector3d", True), ("depth", 6, "double", True),
                ("wrench", 7, "JointWrench", True), ("world", 8, "Entity", False)],
    "Contacts": [("header", 1, "Header", False), ("contact", 2, "Contact", True)],
    # ign-transport's own discovery datagrams (ignition/msgs/discovery.proto).
    "Discovery": [("header", 1, "Header", False), ("version", 2, "uint32", False),
                  ("process_uuid", 3, "string", False), ("type", 4, "Discovery.Type", False),
                  ("flags", 5, "Discovery.Flags", False), ("sub", 6, "Discovery.Subscriber", False),
                  ("pub", 7, "Discovery.Publisher", False)],
    "Discovery.Flags": [("relay", 1, "bool", False), ("no_relay", 2, "bool", False)],
    "Discovery.Subscriber": [("topic", 1, "string", False)],
    "Discovery.Publisher": [("topic", 1, "string", False), ("address", 2, "string", False),
                            ("process_uuid", 3, "string", False), ("node_uuid", 4, "string", False),
                            ("scope", 5, "Discovery.Publisher.Scope", False),
                            ("msg_pub", 6, "Discovery.Publisher.MessagePublisher", False)],
    "Discovery.Publisher.MessagePublisher": [("ctrl", 1, "string", False), ("msg_type", 2, "string", False),
                                             ("throttled", 3, "bool", False), ("msgs_per_sec", 4, "uint64", False)],
}  # fmt: skip

_ENUMS: dict[str, dict[str, int]] = {
    "Discovery.Type": {"UNINITIALIZED": 0, "ADVERTISE": 1, "SUBSCRIBE": 2, "UNADVERTISE": 3, "HEARTBEAT": 4,
                       "BYE": 5, "NEW_CONNECTION": 6, "END_CONNECTION": 7, "SUBSCRIBERS_REQ": 8,
                       "SUBSCRIBERS_REP": 9},
    "Discovery.Publisher.Scope": {"PROCESS": 0, "HOST": 1, "ALL": 2},
    "Entity.Type": {"NONE": 0, "LIGHT": 1, "MODEL": 2, "LINK": 3, "VISUAL": 4, "COLLISION": 5, "SENSOR": 6,
                    "JOINT": 7},
}  # fmt: skip

_SCALARS = {
    "double": descriptor_pb2.FieldDescriptorProto.TYPE_DOUBLE,
    "float": descriptor_pb2.FieldDescriptorProto.TYPE_FLOAT,
    "int64": descriptor_pb2.FieldDescriptorProto.TYPE_INT64,
    "int32": descriptor_pb2.FieldDescriptorProto.TYPE_INT32,
    "uint32": descriptor_pb2.FieldDescriptorProto.TYPE_UINT32,
    "string": descriptor_pb2.FieldDescriptorProto.TYPE_STRING,
    "bool": descriptor_pb2.FieldDescriptorProto.TYPE_BOOL,
    "uint64": descriptor_pb2.FieldDescriptorProto.TYPE_UINT64,
}


@dataclass(frozen=True)
class MessageSet:
    """The message classes, by short name, in the package their descriptors name."""

    package: str
    classes: Mapping[str, Any]  # generated at run time, so typed loosely

    def __getattr__(self, name: str) -> Any:
        try:
            return self.classes[name]
        except KeyError:
            raise AttributeError(name) from None

    def full_name(self, name: str) -> str:
        return f"{self.package}.{name}"

    def parse(self, name: str, data: bytes) -> Any:
        """Bytes as message `name`; raises `DecodeError` for bytes that are not one."""
        message: Message = self.classes[name]()
        try:
            message.ParseFromString(data)
        except ProtobufDecodeError as error:
            raise DecodeError(self.full_name(name), "", 0, f"not a valid protobuf message: {error}") from None
        return message


def _file_descriptor(package: str, geometry_types: Mapping[str, int]) -> descriptor_pb2.FileDescriptorProto:
    file = descriptor_pb2.FileDescriptorProto(
        name=f"viewer_bridge/{package}.proto", package=package, syntax="proto3"
    )
    enums = {"Geometry.Type": dict(geometry_types), **_ENUMS}
    messages: dict[str, descriptor_pb2.DescriptorProto] = {}
    for name, fields in _SCHEMA.items():
        parent, _, short = name.rpartition(".")
        message = (
            messages[parent].nested_type.add(name=short) if parent else file.message_type.add(name=short)
        )
        messages[name] = message
        for field_name, number, type_name, repeated in fields:
            field = message.field.add(name=field_name, number=number, json_name=field_name)
            field.label = field.LABEL_REPEATED if repeated else field.LABEL_OPTIONAL
            if type_name in _SCALARS:
                field.type = _SCALARS[type_name]
            elif type_name in enums:
                field.type, field.type_name = field.TYPE_ENUM, f".{package}.{type_name}"
            else:
                field.type, field.type_name = field.TYPE_MESSAGE, f".{package}.{type_name}"
    for name, values in enums.items():
        parent, _, short = name.rpartition(".")
        enum = messages[parent].enum_type.add(name=short)
        for value_name, number in sorted(values.items(), key=lambda item: item[1]):
            enum.value.add(name=value_name, number=number)
    return file


def _message_set(package: str) -> MessageSet:
    """Build the message classes for `package` in a pool of their own."""
    pool = descriptor_pool.DescriptorPool()
    pool.Add(_file_descriptor(package, tables("ign")["geometry"].types))
    names = [name for name in _SCHEMA if "." not in name]
    classes = {
        name: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"{package}.{name}"))
        for name in names
    }
    return MessageSet(package, classes)


def field_number(message: str, name: str) -> int:
    """A field's number, from `_SCHEMA` (the one place the numbers are written)."""
    return next(number for field, number, _, _ in _SCHEMA[message] if field == name)


MESSAGES = _message_set("gz.msgs")

Package = Literal["ignition", "gz"]
PACKAGES: tuple[Package, ...] = ("gz", "ignition")  # Gazebo Garden and later; Fortress and before


def type_name(name: str, package: Package) -> str:
    """A message's type name in a package, as peers exchange it: `Pose_V` -> `gz.msgs.Pose_V`."""
    return f"{package}.msgs.{name}"


def wire_type_name(name: str, package: Package) -> str:
    """A declared type name as it goes on the wire: a short name (`Pose_V`) in `package`; a full
    name (`ignition.msgs.Pose_V`, a route's own choice, or another package's type) as it is."""
    return name if "." in name else type_name(name, package)


def spellings(full_name: str) -> frozenset[str]:
    """The names one message has across the packages: `gz.msgs.Pose_V` and `ignition.msgs.Pose_V`
    are the same protobuf on the wire. Another package's type has only its own name."""
    package, _, name = full_name.rpartition(".msgs.")
    if package not in PACKAGES:
        return frozenset({full_name})
    return frozenset(type_name(name, other) for other in PACKAGES)


__all__ = [
    "MESSAGES",
    "MessageSet",
    "PACKAGES",
    "Package",
    "field_number",
    "spellings",
    "type_name",
    "wire_type_name",
]
