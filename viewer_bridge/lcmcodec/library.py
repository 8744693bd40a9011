"""Known LCM types and their ROS 2 mapping: STAND-IN UNTIL THE lcmtypes BRANCH LANDS.

This module is a small stand-in, written by the `lcmroutes` branch, of the API the `lcmtypes`
branch implements (`LcmType`, `TypeLibrary`, `ros_topic_for_channel`); the lead replaces it with
that branch's module at merge. It covers what the router side's tests need and nothing more:
`.lcm` files and folders (through `viewer_bridge.lcmcodec.schema`), lcm-gen'd Python modules by
import name (their classes' `__slots__`, `__typenames__`, `__dimensions__`; no constants), the
project's own `lcmtypes/`, and pydrake's `drake` module. `to_cdr` goes through rosbags' typestore
(decode, build the rosbags message, serialize): slow but correct. Recursive types are refused.
"""

from __future__ import annotations

import contextlib
import importlib
import re
import threading
from collections.abc import Iterable, Sequence
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from viewer_bridge.errors import DecodeError, SchemaError
from viewer_bridge.lcmcodec import STRUCTS
from viewer_bridge.lcmcodec.schema import Dimension, Member, StructDef, parse_lcm
from viewer_bridge.lcmcodec.serde import Buffer, LcmMessage, StructCodec, compile_codecs

_ROS_PRIMITIVES = {
    "int8_t": "int8",
    "int16_t": "int16",
    "int32_t": "int32",
    "int64_t": "int64",
    "byte": "uint8",
    "float": "float32",
    "double": "float64",
    "string": "string",
    "boolean": "bool",
}
_DTYPES = {"int8": "i1", "int16": "<i2", "int32": "<i4", "int64": "<i8", "uint8": "u1",
           "float32": "<f4", "float64": "<f8", "bool": "?"}  # fmt: skip
_STORE_LOCK = threading.Lock()


def ros_topic_for_channel(channel: str) -> str:
    """`left-arm.status` -> `/lcm/left_arm_status`."""
    return "/lcm/" + re.sub(r"[^A-Za-z0-9_]", "_", channel)


def _snake(name: str) -> str:
    return re.sub(r"(?<=[a-z0-9])([A-Z])", r"_\1", name).lower()


def _ros_name(full_name: str) -> str:
    package, _, name = full_name.rpartition(".")
    pascal = "".join(part[:1].upper() + part[1:] for part in name.split("_"))
    return f"{package.replace('.', '_') + '_' if package else ''}lcm_msgs/msg/{pascal}"


def _recursive(struct: StructDef, structs: dict[str, StructDef], parents: tuple[str, ...] = ()) -> bool:
    if struct.full_name in parents:
        return True
    return any(
        _recursive(structs[m.type_name], structs, (*parents, struct.full_name))
        for m in struct.members
        if not m.is_primitive
    )


class LcmType:
    """One known LCM type and its ROS 2 mapping (stand-in: see the module's docstring)."""

    def __init__(self, codec: StructCodec, library: TypeLibrary) -> None:
        self.codec = codec
        self.full_name = codec.type_name
        self.packed_fingerprint = codec.packed_fingerprint
        self.source = codec.definition.source
        self._library = library
        self.refused: str | None = None
        if _recursive(codec.definition, library.structs):
            self.refused = f"{self.full_name} is recursive: ROS 2 interfaces cannot refer to themselves"
        self.ros_type: str | None = None if self.refused else _ros_name(self.full_name)

    @cached_property
    def ros2msg(self) -> str:
        return "" if self.ros_type is None else self._library.store.generate_msgdef(self.ros_type, ros_version=2)[0]

    @cached_property
    def rihs01(self) -> str:
        return "" if self.ros_type is None else self._library.store.hash_rihs01(self.ros_type)

    def decode(self, data: Buffer) -> LcmMessage:
        return self.codec.decode(data)

    def to_cdr(self, data: bytes | memoryview) -> bytes:
        """The message as CDR of `ros_type` (little-endian, with its 4-byte header)."""
        assert self.ros_type is not None, self.refused
        message = self._library.rosbags_message(self.codec.definition, self.decode(data))
        with _STORE_LOCK:
            return bytes(self._library.store.serialize_cdr(message, self.ros_type))

    def to_json(self, data: Buffer, *, bytes_summary: bool = True) -> dict[str, object]:
        return self.decode(data).to_dict()


def _module_structs(name: str) -> Iterable[StructDef]:
    """lcm-gen'd classes of a module (and of its package's modules, as `drake` exposes them)."""
    module = importlib.import_module(name)
    for value in vars(module).values():
        if isinstance(value, type) and hasattr(value, "__typenames__"):
            yield _class_struct(value, getattr(module, "__file__", name) or name)


def _class_struct(cls: type, source: str) -> StructDef:
    package, _, _ = cls.__module__.rpartition(".")
    members = []
    for slot, type_name, dims in zip(cls.__slots__, cls.__typenames__, cls.__dimensions__, strict=True):  # type: ignore[attr-defined]
        shape = tuple(
            Dimension(str(d), isinstance(d, str)) for d in (dims or ())
        )
        members.append(Member(slot, type_name, shape))
    return StructDef(package, cls.__name__, tuple(members), (), source)


class TypeLibrary:
    """Every known LCM type (stand-in: see the module's docstring)."""

    def __init__(self, structs: dict[str, StructDef]) -> None:
        self.structs = structs
        self.warnings: list[str] = []
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self._msg: dict[str, str] = {}  # ROS type -> its .msg text
        codecs = compile_codecs(structs)
        self._register({n: c for n, c in codecs.items() if not _recursive(c.definition, structs)})
        self._types: dict[str, LcmType] = {name: LcmType(codec, self) for name, codec in codecs.items()}
        self.warnings.extend(t.refused for t in self._types.values() if t.refused)
        self._by_fingerprint = {t.packed_fingerprint: t for t in self._types.values()}

    @classmethod
    def load(cls, sources: Sequence[str] = (), *, drake: bool = True) -> TypeLibrary:
        """The project's types, pydrake's `drake` module (when importable and `drake`), and `sources`."""
        structs = dict(STRUCTS)
        found: list[StructDef] = []
        if drake:
            with contextlib.suppress(ImportError):  # no pydrake here
                found.extend(_module_structs("drake"))
        for source in sources:
            path = Path(source)
            if path.is_dir():
                for file in sorted(path.rglob("*.lcm")):
                    found.extend(parse_lcm(file.read_text(encoding="utf-8"), str(file)))
            elif path.suffix == ".lcm" or path.exists():
                if not path.exists():
                    raise SchemaError(source, 1, "no such file")
                found.extend(parse_lcm(path.read_text(encoding="utf-8"), str(path)))
            else:
                try:
                    found.extend(_module_structs(source))
                except ImportError as error:
                    raise SchemaError(source, 1, f"neither a .lcm file or folder nor a module ({error})") from None
        for struct in found:
            structs.setdefault(struct.full_name, struct)
        return cls(structs)

    def _register(self, codecs: dict[str, StructCodec]) -> None:
        texts: dict[str, Any] = {}
        for codec in codecs.values():
            lines = []
            for member in codec.definition.members:
                base = _ROS_PRIMITIVES.get(member.type_name) or _ros_name(member.type_name).replace("/msg/", "/")
                fixed = len(member.dims) == 1 and not member.dims[0].is_variable
                suffix = f"[{member.dims[0].size}]" if fixed else "[]" if member.dims else ""
                lines.append(f"{base}{suffix} {_snake(member.name)}")
            self._msg[_ros_name(codec.type_name)] = "\n".join(lines) + "\n"
            texts.update(get_types_from_msg(self._msg[_ros_name(codec.type_name)], _ros_name(codec.type_name)))
        self.store.register(texts)

    def rosbags_message(self, struct: StructDef, message: LcmMessage) -> Any:
        fields = {}
        for member in struct.members:
            value = getattr(message, member.name)
            if member.dims:
                value = _flat(value, len(member.dims))
                if member.type_name in _ROS_PRIMITIVES and member.type_name != "string":
                    value = np.asarray(value, dtype=_DTYPES[_ROS_PRIMITIVES[member.type_name]])
                elif not member.is_primitive:
                    value = [self.rosbags_message(self.structs[member.type_name], item) for item in value]
            elif not member.is_primitive:
                value = self.rosbags_message(self.structs[member.type_name], value)
            elif member.type_name == "boolean":
                value = bool(value)
            fields[_snake(member.name)] = value
        return self.store.types[_ros_name(struct.full_name)](**fields)

    def for_data(self, data: Buffer) -> LcmType | None:
        """The type the first 8 bytes name (maybe a refused one), or None."""
        return self._by_fingerprint.get(bytes(data[:8]))

    def get(self, full_name: str) -> LcmType:
        return self._types[full_name]

    def types(self) -> list[LcmType]:
        return list(self._types.values())

    def ros_definitions(self) -> dict[str, str]:
        return dict(self._msg)


def _flat(value: Any, depth: int) -> list[Any]:
    if isinstance(value, np.ndarray):
        return list(value.ravel())
    items = list(value)
    for _ in range(depth - 1):
        items = [inner for outer in items for inner in outer]
    return items


__all__ = ["DecodeError", "LcmType", "TypeLibrary", "ros_topic_for_channel"]
