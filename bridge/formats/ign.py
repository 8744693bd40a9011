"""ignition / gz protobuf messages (`Model`, `Model_V`, `Pose_V`, `PosesStamped`) to and from the scene.

The message types are built at import from `_SCHEMA` below (field numbers from ign-msgs 8, see
docs/PROTOCOLS.md section 4) into a protobuf descriptor pool, once per package: `IGNITION`
(`ignition.msgs`, as Debian's ign-transport 11 speaks) and `GZ` (`gz.msgs`, newer Gazebo). The
wire format is the `protobuf` package's; only the fields the bridge uses are declared, and a
receiver with the full `.proto` files reads them (unknown fields are skipped both ways).

Which shape becomes which `Geometry` is in `mappings/ign.yaml`.
"""

from __future__ import annotations

import base64
import re
import struct
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.message import DecodeError as ProtobufDecodeError
from google.protobuf.message import Message

from bridge.errors import DecodeError, SceneError
from bridge.formats import protowire as wire
from bridge.mappings import FormatTables, ShapeRule
from bridge.scene import (
    FileContents,
    FloatArray,
    Geometry,
    InMemoryMesh,
    Line,
    Link,
    LinkPoses,
    Pose,
    Scene,
    Shape,
    TriangleMesh,
    link_poses_from_xyzw,
    pose_from_xyzw,
    pose_rows_xyzw,
    xyzw_from_wxyz,
)
from bridge.sim_time import ms_from_sec_nsec, sec_nsec_from_ms
from bridge.skipped import per_geometry

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
                       "BYE": 5, "NEW_CONNECTION": 6, "END_CONNECTION": 7},
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
    """The message classes of one package (`ignition.msgs` or `gz.msgs`), by short name."""

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


def message_set(package: str) -> MessageSet:
    """Build the message classes for `package` in a pool of their own."""
    pool = descriptor_pool.DescriptorPool()
    pool.Add(_file_descriptor(package, TABLES["geometry"].types))
    names = [name for name in _SCHEMA if "." not in name]
    classes = {
        name: message_factory.GetMessageClass(pool.FindMessageTypeByName(f"{package}.{name}"))
        for name in names
    }
    return MessageSet(package, classes)


def _data_uri_obj(shape: TriangleMesh) -> dict[str, Any]:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in shape.vertices.tolist()]
    lines += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in shape.triangles.tolist()]
    text = "\n".join(lines) + "\n"
    return {"mesh.filename": "data:model/obj;base64," + base64.b64encode(text.encode()).decode("ascii")}


def _data_uri_file(shape: InMemoryMesh) -> dict[str, Any]:
    file = shape.mesh_file
    media = f"model/{file.extension.lstrip('.')};name={file.filename_hint}"
    return {"mesh.filename": f"data:{media};base64," + base64.b64encode(file.contents).decode("ascii")}


def _polyline_points(shape: Line) -> dict[str, Any]:
    return {"points": shape.path().tolist()}


TABLES = FormatTables(
    "ign", {"obj_data_uri": _data_uri_obj, "file_data_uri": _data_uri_file, "polyline_points": _polyline_points}
)


IGNITION = message_set("ignition.msgs")
GZ = message_set("gz.msgs")

# --- poses -------------------------------------------------------------------------------------------


def _set_pose(target: Any, pose: Pose) -> None:
    target.position.x, target.position.y, target.position.z = pose.position
    orientation = target.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = pose.quaternion_xyzw


def _set_stamp(time: Any, timestamp_ms: int) -> None:
    time.sec, time.nsec = sec_nsec_from_ms(timestamp_ms)


def pose_v(poses: LinkPoses, msgs: MessageSet = IGNITION) -> Any:
    """A draw as `Pose_V`: one `Pose` per link, named with the link's Drake name, header stamped."""
    message = msgs.Pose_V()
    _set_stamp(message.header.stamp, poses.timestamp_ms)
    _fill_poses(message.pose, poses)
    return message


def poses_stamped(poses: LinkPoses, msgs: MessageSet = IGNITION) -> Any:
    """The legacy `PosesStamped`: like `Pose_V`, with the sim time in `time` as well."""
    message = msgs.PosesStamped()
    _set_stamp(message.header.stamp, poses.timestamp_ms)
    _set_stamp(message.time, poses.timestamp_ms)
    _fill_poses(message.pose, poses)
    return message


def _fill_poses(repeated: Any, poses: LinkPoses) -> None:
    values = np.concatenate((poses.positions, xyzw_from_wxyz(poses.quaternions_wxyz)), axis=1).tolist()
    for index, (name, (x, y, z, qx, qy, qz, qw)) in enumerate(zip(poses.names, values, strict=True)):
        pose = repeated.add(name=name, id=index)
        position, orientation = pose.position, pose.orientation
        position.x, position.y, position.z = x, y, z
        orientation.x, orientation.y, orientation.z, orientation.w = qx, qy, qz, qw


def _field(message: str, name: str) -> int:
    """A field's number, from `_SCHEMA` (the one place the numbers are written)."""
    return next(number for field, number, _, _ in _SCHEMA[message] if field == name)


_HEADER, _HEADER_STAMP = _field("Pose_V", "header"), _field("Header", "stamp")
# The keys of Time.sec and Time.nsec, varints each left out when 0 (proto3).
_TIME_SEC, _TIME_NSEC = (wire.key(_field("Time", name), wire.VARINT) for name in ("sec", "nsec"))
_DOUBLE_FIELDS = tuple(_field("Vector3d", axis) for axis in "xyz") + tuple(
    _field("Quaternion", axis) for axis in "xyzw"
)  # the 7 doubles of a pose, in `pose_rows_xyzw` order: position x y z, orientation x y z w


class PosesEncoder:
    """draw arrays -> `Pose_V` (or `PosesStamped`) bytes, byte for byte as protobuf writes them
    from `pose_v` (`poses_stamped`), without building a message per link.

    proto3 leaves out a double that is +0.0 and an id that is 0, so the bytes of a pose depend
    on its name, its index and which of its seven doubles are zero. For one list of names and
    one such pattern the poses are laid out once, with the byte offset of every double written;
    a draw then copies that template and writes its doubles, and only a new pattern (a value
    becoming exactly 0 or leaving 0) lays the poses out again.
    """

    def __init__(self, message: str = "Pose_V") -> None:
        """`message` is `Pose_V` or `PosesStamped` (the package, ignition or gz, is not in the bytes)."""
        self.message = message
        self._pattern: tuple[tuple[str, ...], bytes] = ((), b"")
        self._layout = _PosesLayout([], np.zeros((0, 7), dtype=bool))
        self._lock = threading.Lock()  # routes on several threads may share an encoder

    def encode(self, poses: LinkPoses) -> bytes:
        rows = pose_rows_xyzw(poses.positions, poses.quaternions_wxyz)
        written = rows.view(np.uint64) != 0  # +0.0 is all zero bits; -0.0 is written
        zeros = written.tobytes()
        head = self._head(poses.timestamp_ms)
        with self._lock:
            names, known_zeros = self._pattern
            if zeros != known_zeros or (poses.names is not names and poses.names != names):
                self._layout = _PosesLayout(self._lay_out(poses.names, written), written)
                self._pattern = (poses.names, zeros)
            return b"".join((head, self._layout.write(rows).data))

    def _head(self, timestamp_ms: int) -> bytes:
        """The header with the stamp (and for `PosesStamped` the time field): before the poses."""
        seconds, nanoseconds = sec_nsec_from_ms(timestamp_ms)
        time = (_TIME_SEC + wire.varint(seconds) if seconds else b"") + (
            _TIME_NSEC + wire.varint(nanoseconds) if nanoseconds else b""
        )
        head = wire.length_delimited(_HEADER, wire.length_delimited(_HEADER_STAMP, time))
        if self.message == "PosesStamped":
            head += wire.length_delimited(_field(self.message, "time"), time)
        return head

    def _lay_out(self, names: Sequence[str], written: npt.NDArray[np.bool_]) -> list[tuple[bytes, list[int]]]:
        """Every pose's bytes (zeros for its doubles) and where its written doubles sit in them."""
        entries = []
        pose_field = _field(self.message, "pose")
        for index, (name, present) in enumerate(zip(names, written.tolist(), strict=True)):
            position, position_places = _doubles(_DOUBLE_FIELDS[:3], present[:3])
            orientation, orientation_places = _doubles(_DOUBLE_FIELDS[3:], present[3:])
            head = wire.length_delimited(_field("Pose", "name"), name.encode()) + wire.varint_field(
                _field("Pose", "id"), index
            )
            position_head = wire.key(_field("Pose", "position"), wire.LENGTH_DELIMITED) + wire.varint(len(position))
            orientation_head = wire.key(_field("Pose", "orientation"), wire.LENGTH_DELIMITED) + wire.varint(
                len(orientation)
            )
            body = b"".join((head, position_head, position, orientation_head, orientation))
            entry_head = wire.key(pose_field, wire.LENGTH_DELIMITED) + wire.varint(len(body))
            at = len(entry_head) + len(head) + len(position_head)
            places = [at + place for place in position_places]
            at += len(position) + len(orientation_head)
            places += [at + place for place in orientation_places]
            entries.append((entry_head + body, places))
        return entries


class _PosesLayout:
    """The poses' bytes for one names-and-zeros pattern, kept in a buffer whose doubles a draw
    overwrites (all of them, so the rest stays the template).

    The doubles sit at any byte offset; numpy writes them as float64 through 8 views of the
    buffer, one per offset modulo 8, which is several times faster than writing 8 bytes each.
    """

    def __init__(self, entries: list[tuple[bytes, list[int]]], written: npt.NDArray[np.bool_]) -> None:
        places, size = [], 0
        for entry, entry_places in entries:
            places += [size + place for place in entry_places]
            size += len(entry)
        self.buffer = np.frombuffer(bytearray(b"".join(entry for entry, _ in entries)), dtype=np.uint8)
        offsets = np.asarray(places, dtype=np.intp)
        sources = np.flatnonzero(written.reshape(-1))  # which of the N x 7 values, in `offsets` order
        by_residue = np.argsort(offsets % 8, kind="stable")
        self.sources = sources[by_residue]  # gathered in one go, then written a residue at a time
        offsets = offsets[by_residue]
        bounds = np.searchsorted(offsets % 8, np.arange(9))
        self.views = []
        for residue in range(8):
            part = slice(bounds[residue], bounds[residue + 1])
            words = (len(self.buffer) - residue) // 8
            view = self.buffer[residue : residue + 8 * words].view("<f8")
            self.views.append((view, (offsets[part] - residue) // 8, part))

    def write(self, rows: FloatArray) -> npt.NDArray[np.uint8]:
        values = rows.reshape(-1)[self.sources]
        for view, slots, part in self.views:
            view[slots] = values[part]
        return self.buffer


def _doubles(fields: Sequence[int], present: Sequence[bool]) -> tuple[bytes, list[int]]:
    """The doubles of a message with their keys (zeros for now), and where each written one sits."""
    out, places = b"", []
    for field, written in zip(fields, present, strict=True):
        if written:
            out += wire.key(field, wire.FIXED64)
            places.append(len(out))
            out += bytes(8)
    return out, places


def _xyzw(pose: Any) -> list[float]:
    if not pose.HasField("orientation"):
        return [0.0, 0.0, 0.0, 1.0]
    orientation = pose.orientation
    return [orientation.x, orientation.y, orientation.z, orientation.w]


def poses_from_pose_v(message: Any, robot_nums: Mapping[str, int] | None = None) -> LinkPoses:
    """A `Pose_V` or `PosesStamped` back as link poses (names from `Pose.name`).

    `robot_nums` (link name -> model instance, e.g. from the scene's load) fills what the
    message does not carry; links it lacks get 0. A Pose without an orientation is not rotated
    (the identity, as every gz tool reads it). Raises `SceneError` for a non-finite position or
    an orientation given that is not a rotation.
    """
    names = [p.name for p in message.pose]
    positions = [[p.position.x, p.position.y, p.position.z] for p in message.pose]
    xyzw = [_xyzw(p) for p in message.pose]
    numbers = [(robot_nums or {}).get(name, 0) for name in names]
    stamp = message.header.stamp
    timestamp_ms = ms_from_sec_nsec(stamp.sec, stamp.nsec)
    return link_poses_from_xyzw(timestamp_ms, names, numbers, positions, xyzw, "pose")


def _pose_from(message: Any, what: str) -> Pose:
    p, q = message.position, message.orientation
    return pose_from_xyzw([p.x, p.y, p.z], [q.x, q.y, q.z, q.w], what)


# --- geometry ---------------------------------------------------------------------------------------


def _set_field(message: Any, path: str, value: Any) -> None:
    *parents, last = path.split(".")
    for name in parents:
        message = getattr(message, name)
    target: Any = getattr(message, last) if isinstance(value, list) else None
    if hasattr(target, "add"):  # a repeated Vector3d: one per point
        for point in value:
            item = target.add()
            item.x, item.y, item.z = point
    elif isinstance(value, list):  # a vector: Vector3d or Vector2d
        for axis, component in zip("xyz", value, strict=False):
            setattr(target, axis, component)
    else:
        setattr(message, last, value)


def _get_field(message: Any, path: str, rule: ShapeRule) -> Any:
    *parents, last = path.split(".")
    for name in parents:
        message = getattr(message, name)
    value = getattr(message, last)
    if path in rule.list_fields:
        return [getattr(value, axis) for axis in "xyz"[: len(rule.fields[path])]]
    return value


def geometry_message(shape: Shape, msgs: MessageSet = IGNITION) -> Any:
    """One shape as a `Geometry` (a half-space becomes a PLANE; see mappings/ign.yaml)."""
    message = msgs.Geometry()
    _fill_geometry(message, shape)
    return message


def _fill_geometry(message: Any, shape: Shape) -> None:
    ((rule, _, _),) = TABLES["geometry"].expand(shape)  # a SceneError for a shape ign cannot hold
    message.type = rule.type_code
    for path, value in rule.values(shape).items():
        _set_field(message, path, value)


def shape_from_geometry(message: Any) -> Shape:
    """A `Geometry` back as a scene shape; raises `SceneError` for one the bridge cannot read."""
    table = TABLES["geometry"]
    filename = message.mesh.filename if message.type == table.types["MESH"] else ""
    if filename.startswith("data:"):
        return _shape_from_data_uri(filename, message)
    candidates = [rule for rule in table.rules.values() if rule.type_code == message.type and rule.invertible]
    if not candidates:
        raise SceneError(f"Geometry type {table.type_name(message.type)} has no scene shape")
    rule = candidates[0]
    try:
        return rule.shape_from({path: _get_field(message, path, rule) for path in rule.fields})
    except ValueError as error:
        raise SceneError(f"Geometry: {error}") from None


_DATA_URI = re.compile(
    r"^data:model/(?P<extension>[^;,]+)(?:;name=(?P<name>[^;,]*))?;base64,(?P<data>.*)$", re.S
)


def _shape_from_data_uri(uri: str, message: Any) -> Shape:
    match = _DATA_URI.match(uri)
    if match is None:
        raise SceneError("Geometry: mesh.filename is a data: URI the bridge does not write")
    try:
        data = base64.b64decode(match["data"], validate=True)
    except ValueError as error:
        raise SceneError(f"Geometry: mesh.filename data is not base64 ({error})") from None
    if match["name"] is None:
        return _parse_obj(data.decode("utf-8", errors="replace"))
    scale = message.mesh.scale
    file = FileContents(data, "." + match["extension"], match["name"])
    return InMemoryMesh(file, {}, (scale.x, scale.y, scale.z))


def _parse_obj(text: str) -> TriangleMesh:
    """The `v` and `f` lines of an OBJ as written by `_data_uri_obj` (three values each)."""
    vertices, faces = [], []
    for number, line in enumerate(text.splitlines(), 1):
        kind, *values = line.split() or [""]
        if kind not in ("v", "f"):
            continue
        try:
            if len(values) < 3:
                raise ValueError(f"needs 3 values, has {len(values)}")
            if kind == "v":
                vertices.append([float(value) for value in values[:3]])
            else:
                faces.append([int(value.split("/")[0]) - 1 for value in values[:3]])
        except ValueError as error:
            raise SceneError(f"Geometry: mesh array OBJ line {number}: {error}") from None
    vertex_array = np.array(vertices, dtype=np.float64).reshape(-1, 3)
    face_array = np.array(faces, dtype=np.int64).reshape(-1, 3)
    if not np.isfinite(vertex_array).all():
        raise SceneError("Geometry: mesh array OBJ has a vertex that is not finite")
    if face_array.size and (face_array.min() < 0 or face_array.max() >= len(vertex_array)):
        raise SceneError("Geometry: mesh array OBJ refers to a vertex it does not have")
    return TriangleMesh(vertex_array, face_array)


# --- models -------------------------------------------------------------------------------------------

_ROBOT_NUM = "robot_num"  # kept in each Link's header data so that robot_num survives the trip


def _fill_link(message: Any, link: Link, pose: Pose) -> None:
    message.name = link.name
    message.header.data.add(key=_ROBOT_NUM, value=[str(link.robot_num)])
    _set_pose(message.pose, pose)

    def visual(index: int, geometry: Geometry) -> Any:
        """The geometry's visual in a Link of its own: merged once it is made."""
        part = type(message)()
        visual = part.visual.add(name=f"{link.name}::visual_{index}", id=index, parent_name=link.name)
        _set_pose(visual.pose, geometry.pose)
        _fill_geometry(visual.geometry, geometry.shape)
        diffuse = visual.material.diffuse  # float32 on the wire, as Drake's colour is
        diffuse.r, diffuse.g, diffuse.b, diffuse.a = geometry.color
        return part

    for part in per_geometry(link, visual):
        message.MergeFrom(part)



def model(scene: Scene, name: str = "drake", msgs: MessageSet = IGNITION) -> Any:
    """A load as one `Model` with a `Link` per Drake link and a `Visual` per geometry.

    Link poses are the scene's world poses (identity before the first draw); visual poses are
    in the link frame, as Drake's are.
    """
    message = msgs.Model(name=name)
    _set_pose(message.pose, Pose())
    for link in scene.links:
        _fill_link(message.link.add(), link, scene.link_pose(link))
    return message


def model_bytes(scene: Scene, name: str = "drake", msgs: MessageSet = IGNITION) -> bytes:
    """`model(scene, name, msgs).SerializeToString()`, written from pieces instead of objects.

    A Model is its fields' encodings in field-number order, so it is written by concatenation:
    each distinct shape's `Geometry` is serialised once by protobuf, and poses and colours are
    packed here, leaving out zeros as proto3 does (by bit pattern: -0.0 is written). Filling a
    `Model` object field by field was most of a load's time.
    """
    try:
        return _model_payload(_ModelWriter(msgs), scene, scene.links, name, 0)
    except OverflowError:  # a colour beyond float32: the object path writes it as protobuf does
        return bytes(model(scene, name, msgs).SerializeToString())


def model_v_bytes(scene: Scene, msgs: MessageSet = IGNITION) -> bytes:
    """`model_v(scene, msgs).SerializeToString()`, written as `model_bytes` writes a Model."""
    groups: dict[int, list[Link]] = {}
    for link in scene.links:
        groups.setdefault(link.robot_num, []).append(link)
    if any(not 0 <= robot_num < 2**32 for robot_num in groups):  # no uint32 id: as the object path refuses it
        return bytes(model_v(scene, msgs).SerializeToString())
    try:
        writer = _ModelWriter(msgs)
        return b"".join(
            wire.submessage(_MODELS, _model_payload(writer, scene, links, _model_name(links[0]), robot_num))
            for robot_num, links in groups.items()
        )
    except OverflowError:
        return bytes(model_v(scene, msgs).SerializeToString())


def _model_payload(
    writer: _ModelWriter, scene: Scene, links: Sequence[Link], name: str, model_id: int
) -> bytes:
    poses = _link_pose_values(scene, links)
    identity = wire.submessage(_MODEL_POSE, _pose_bytes(Pose()))
    head = (
        wire.string_field(_MODEL_NAME, name)
        + (_MODEL_ID + wire.varint(model_id) if model_id else b"")
        + identity
    )
    return head + b"".join(
        wire.submessage(_MODEL_LINK, writer.link(link, pose)) for link, pose in zip(links, poses, strict=True)
    )


# Field keys (docs/PROTOCOLS.md section 4): Model{name=2, id=3, pose=5, link=7}; Link{header=1, name=3,
# pose=10, visual=11}; Header{data=2}, its Map{key=1, value=2}; Visual{name=2, id=3,
# parent_name=4, pose=9, geometry=10, material=11}; Material{diffuse=6}; Color{r..a=2..5};
# Pose{position=4, orientation=5}; Vector3d{x..z=2..4}; Quaternion{x..w=2..5}.
_MODEL_NAME, _MODEL_ID, _MODEL_POSE, _MODEL_LINK = (
    wire.key(2, 2),
    wire.key(3, 0),
    wire.key(5, 2),
    wire.key(7, 2),
)
_MODELS = wire.key(2, 2)  # Model_V{models=2}
_LINK_HEADER, _LINK_NAME, _LINK_POSE, _LINK_VISUAL = (
    wire.key(1, 2),
    wire.key(3, 2),
    wire.key(10, 2),
    wire.key(11, 2),
)
_VISUAL_NAME, _VISUAL_ID, _VISUAL_PARENT = wire.key(2, 2), wire.key(3, 0), wire.key(4, 2)
_VISUAL_POSE, _VISUAL_GEOMETRY, _VISUAL_MATERIAL = wire.key(9, 2), wire.key(10, 2), wire.key(11, 2)
_DIFFUSE = wire.key(6, 2)
_FLOAT_KEYS = [wire.key(number, wire.FIXED32) for number in (2, 3, 4, 5)]
_FLOAT, _ZERO_FLOAT = struct.Struct("<f"), bytes(4)


_POSE = wire.PoseWriter(4, 5, 2)  # Pose{position=4, orientation=5}, their components from 2


def _link_pose_values(scene: Scene, links: Sequence[Link]) -> list[list[float]]:
    """Each link's world pose as x, y, z, qx, qy, qz, qw (`Scene.link_pose`, for all links at once)."""
    if scene.poses is None:
        return [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]] * len(links)
    count = len(scene.poses)
    values = np.zeros((count + 1, 7))
    values[count, 6] = 1.0  # the last row: identity, for links the frame lacks (e.g. world)
    values[:count, :3] = scene.poses.positions
    values[:count, 3:] = xyzw_from_wxyz(scene.poses.quaternions_wxyz)
    rows = [scene.poses.row_of(link.name) for link in links]
    chosen: list[list[float]] = values[[count if row is None else row for row in rows]].tolist()
    return chosen


def _pose_bytes(pose: Pose) -> bytes:
    return _pose_values_bytes([*pose.position, *pose.quaternion_xyzw])


def _pose_values_bytes(values: Sequence[float]) -> bytes:
    return _POSE.pose(*values)


def _material(color: Sequence[float]) -> bytes:
    """Material{diffuse}: float32 on the wire (OverflowError beyond float32's range)."""
    packed = [_FLOAT.pack(value) for value in color]
    diffuse = b"".join(
        key + data for key, data in zip(_FLOAT_KEYS, packed, strict=True) if data != _ZERO_FLOAT
    )
    return wire.submessage(_VISUAL_MATERIAL, wire.submessage(_DIFFUSE, diffuse))


class _ModelWriter:
    """The pieces of one Model: Geometry bytes per distinct shape, header bytes per robot_num."""

    def __init__(self, msgs: MessageSet) -> None:
        self.msgs = msgs
        self.geometries: dict[int, tuple[Shape, bytes]] = {}  # by id: the scene's shapes, held here
        self.headers: dict[int, bytes] = {}
        # By `wire.exact_key`: 0.0 and -0.0 are equal floats but written differently.
        self.poses: dict[bytes, bytes] = {}  # geometry poses repeat (the same part on many links)
        self.colors: dict[bytes, bytes] = {}

    def link(self, link: Link, pose: Sequence[float]) -> bytes:
        header = self.headers.get(link.robot_num)
        if header is None:
            value = wire.submessage(wire.key(2, wire.LENGTH_DELIMITED), str(link.robot_num).encode())
            entry = wire.string_field(wire.key(1, wire.LENGTH_DELIMITED), _ROBOT_NUM) + value
            header = self.headers[link.robot_num] = wire.submessage(
                _LINK_HEADER, wire.submessage(wire.key(2, 2), entry)
            )
        parts = [
            header,
            wire.string_field(_LINK_NAME, link.name),
            wire.submessage(_LINK_POSE, _pose_values_bytes(pose)),
        ]
        parts += per_geometry(
            link, lambda index, geometry: wire.submessage(_LINK_VISUAL, self.visual(link.name, index, geometry))
        )
        return b"".join(parts)

    def visual(self, link_name: str, index: int, geometry: Geometry) -> bytes:
        values = (*geometry.pose.position, *geometry.pose.quaternion_xyzw)
        pose_key = wire.exact_key(values)
        pose = self.poses.get(pose_key)
        if pose is None:
            pose = self.poses[pose_key] = wire.submessage(_VISUAL_POSE, _pose_values_bytes(values))
        color_key = wire.exact_key(geometry.color)
        material = self.colors.get(color_key)
        if material is None:
            material = self.colors[color_key] = _material(geometry.color)
        return b"".join((
            wire.string_field(_VISUAL_NAME, f"{link_name}::visual_{index}"),
            _VISUAL_ID + wire.varint(index) if index else b"",
            wire.string_field(_VISUAL_PARENT, link_name),
            pose,
            wire.submessage(_VISUAL_GEOMETRY, self.geometry(geometry.shape)),
            material,
        ))  # fmt: skip

    def geometry(self, shape: Shape) -> bytes:
        known = self.geometries.get(id(shape))
        if known is None:
            known = self.geometries[id(shape)] = (shape, bytes(geometry_message(shape, self.msgs).SerializeToString()))
        return known[1]


def model_v(scene: Scene, msgs: MessageSet = IGNITION) -> Any:
    """A load as `Model_V`: one `Model` per robot_num (model instance), id = robot_num."""
    message = msgs.Model_V()
    by_robot: dict[int, Any] = {}
    for link in scene.links:
        if link.robot_num not in by_robot:
            by_robot[link.robot_num] = message.models.add(name=_model_name(link), id=link.robot_num)
            _set_pose(by_robot[link.robot_num].pose, Pose())
        _fill_link(by_robot[link.robot_num].link.add(), link, scene.link_pose(link))
    return message


def _model_name(link: Link) -> str:
    """`plant::iiwa::iiwa_link_0` -> `plant::iiwa`: the source and model instance part."""
    parts = link.name.split("::")
    return "::".join(parts[:-1]) if len(parts) > 1 else link.name


def scene_from_model(message: Any) -> Scene:
    """A `Model` or `Model_V` back as a scene (the reverse of `model` / `model_v`).

    Raises `SceneError` naming the link and visual whose geometry or pose makes no shape.
    """
    models: Sequence[Any] = message.models if hasattr(message, "models") else [message]
    links = []
    for model_message in models:
        for link in model_message.link:
            geometries = []
            for index, visual in enumerate(link.visual):
                where = f"link {link.name!r} visual {index}"
                try:
                    shape = shape_from_geometry(visual.geometry)
                except SceneError as error:
                    raise SceneError(f"{where}: {error}") from None
                color = visual.material.diffuse
                pose = _pose_from(visual.pose, where)
                geometries.append(Geometry(shape, pose, (color.r, color.g, color.b, color.a)))
            links.append(Link(link.name, _robot_num(link, model_message), tuple(geometries)))
    return Scene(tuple(links))


def _robot_num(link: Any, model_message: Any) -> int:
    for entry in link.header.data:
        if entry.key == _ROBOT_NUM and entry.value:
            try:
                return int(entry.value[0])
            except ValueError:
                break
    return int(model_message.id)


__all__ = [
    "GZ",
    "IGNITION",
    "MessageSet",
    "PosesEncoder",
    "geometry_message",
    "message_set",
    "model",
    "model_bytes",
    "model_v",
    "model_v_bytes",
    "pose_v",
    "poses_from_pose_v",
    "poses_stamped",
    "scene_from_model",
    "shape_from_geometry",
]
