"""The test corpus of LCM types that are not the project's (tests/lcmtypes_corpus/), lcm-gen's own
Python for it, random messages built with lcm-gen's classes, and the independent CDR readers.

Every value check compares what an independent reader (rosbags' typestore, mcap_ros2's dynamic
decoder) makes of our CDR with what lcm-gen's generated class decodes from the same LCM bytes.
"""

from __future__ import annotations

import importlib
import struct
import subprocess
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest
from hypothesis import strategies as st

from tests.conftest import SCRIPTS
from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.library import LcmType, TypeLibrary
from viewer_bridge.lcmcodec.rosnames import field_name
from viewer_bridge.lcmcodec.schema import Member, StructDef

CORPUS = Path(__file__).resolve().parent.parent / "lcmtypes_corpus"
TRANSLATOR_CORPUS = CORPUS.parent / "translators" / "lcm_corpus"  # another lab's: vbtest_lab, vbtest_geo
# plain_status_t after its arrays: tags[2] ("a", ""), odd, fixedShorts[3], bits[3], fixedLongs[2].
PLAIN_TAIL = struct.pack(">I2sI1sb3h3B2q", 2, b"a\0", 1, b"\0", -1, 1, -2, 3, 0, 2, 255, 5, -6)
INT_BITS = {"int8_t": 8, "int16_t": 16, "int32_t": 32, "int64_t": 64}


Refused = TypeVar("Refused", bound=DecodeError)


def assert_refused(
    convert: Callable[[Any], bytes], value: Any, error: type[Refused], known: LcmType, field: str, reason: str
) -> Refused:
    """`convert(value)` (a way back to LCM of `known`) raises `error` naming `field`, with `reason` in its reason."""
    with pytest.raises(error) as caught:
        convert(value)
    assert caught.value.field == field, caught.value
    assert reason in caught.value.reason, caught.value
    assert caught.value.type_name == known.full_name
    return caught.value


def generate_lcmgen(out: Path, corpus: Path = CORPUS) -> dict[str, type]:
    """lcm-gen --python for every .lcm file of `corpus` into `out`, imported: classes by full name."""
    # One run per file: lcm-gen carries a file's package over to the next file of a run.
    for schema in sorted(corpus.rglob("*.lcm")):
        subprocess.run([str(SCRIPTS / "lcm-gen"), "--python", "--ppath", str(out), str(schema)], check=True)
    sys.path.insert(0, str(out))
    try:
        classes: dict[str, type] = {}
        for path in out.rglob("*.py"):
            if path.stem == "__init__":
                continue
            module = ".".join(path.relative_to(out).with_suffix("").parts)
            classes[module] = getattr(importlib.import_module(module), path.stem)
        return classes
    finally:
        sys.path.remove(str(out))


def _leaf(type_name: str) -> st.SearchStrategy[Any]:
    if type_name in INT_BITS:
        bits = INT_BITS[type_name]
        return st.integers(-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    if type_name == "float":
        return st.floats(width=32, allow_nan=False)
    if type_name == "double":
        return st.floats(allow_nan=False)
    if type_name == "boolean":
        return st.booleans()
    if type_name == "string":
        return st.text(max_size=8)
    raise AssertionError(type_name)


def lcmgen_messages(
    struct: StructDef, structs: Mapping[str, StructDef], classes: Mapping[str, type], depth: int = 0
) -> st.SearchStrategy[Any]:
    """Random messages of `struct`, built as lcm-gen's class objects (recursive types: 3 levels)."""
    counts = {dim.size for member in struct.members for dim in member.dims if dim.is_variable}

    @st.composite
    def build(draw: st.DrawFn) -> Any:
        message = classes[struct.full_name]()
        values: dict[str, Any] = {}
        for member in struct.members:
            if member.name in counts:
                value: Any = draw(st.integers(0, 3 if depth < 2 else 0))
            elif member.dims:
                shape = [values[dim.size] if dim.is_variable else dim.count for dim in member.dims]
                value = draw(_array(member, shape, structs, classes, depth))
            else:
                value = draw(_element(member, structs, classes, depth))
            values[member.name] = value
            setattr(message, member.name, value)
        return message

    return build()


def _element(
    member: Member, structs: Mapping[str, StructDef], classes: Mapping[str, type], depth: int
) -> Any:
    if member.type_name == "byte":
        return st.integers(0, 255)
    if member.is_primitive:
        return _leaf(member.type_name)
    return lcmgen_messages(structs[member.type_name], structs, classes, depth + 1)


def _array(member: Member, shape: list[int], structs: Mapping[str, StructDef], classes: Mapping[str, type],
           depth: int) -> st.SearchStrategy[Any]:  # fmt: skip
    if len(shape) == 1 and member.type_name == "byte":
        return st.binary(min_size=shape[0], max_size=shape[0])
    inner = (
        _array(member, shape[1:], structs, classes, depth)
        if len(shape) > 1
        else _element(member, structs, classes, depth)
    )
    return st.lists(inner, min_size=shape[0], max_size=shape[0])


def expected(message: Any, struct: StructDef, structs: Mapping[str, StructDef]) -> dict[str, Any]:
    """lcm-gen's decoded message as the ROS 2 message should hold it: ROS field names, arrays
    flattened in row-major order, bytes as ints, nested messages as dicts."""
    result: dict[str, Any] = {}
    for member in struct.members:
        value = getattr(message, member.name)
        if member.dims:
            result[field_name(member.name)] = [
                _leaf_value(item, member, structs) for item in _flat(value, len(member.dims), member)
            ]
        else:
            result[field_name(member.name)] = _leaf_value(value, member, structs)
    return result


def _flat(value: Any, depth: int, member: Member) -> list[Any]:
    if depth == 1:
        return list(value)
    return [item for row in value for item in _flat(row, depth - 1, member)]


def _leaf_value(value: Any, member: Member, structs: Mapping[str, StructDef]) -> Any:
    if member.type_name == "boolean":
        return bool(value)
    if member.is_primitive:
        return value
    return expected(value, structs[member.type_name], structs)


def plain(value: Any) -> Any:
    """A decoded ROS message (rosbags' or mcap_ros2's objects) as dicts, lists and Python scalars."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, bytes | bytearray):  # mcap_ros2's uint8[]
        return list(value)
    if isinstance(value, list | tuple):
        return [plain(item) for item in value]
    if hasattr(value, "__slots__") and not isinstance(value, str | bytes):
        names = [name for name in value.__slots__ if name[0].islower()]
        return {
            name: plain(getattr(value, name))
            for name in names
            if name != "structure_needs_at_least_one_member"
        }
    if hasattr(value, "__dataclass_fields__"):
        # Constants are class-level fields of rosbags' classes: upper-case, and not message content.
        return {name: plain(getattr(value, name)) for name in value.__dataclass_fields__
                if name[0].islower() and name != "structure_needs_at_least_one_member"}  # fmt: skip
    if isinstance(value, np.generic):
        return value.item()
    return value


def rosbags_reader(library: TypeLibrary) -> Callable[[bytes, str], Any]:
    """rosbags' CDR deserializer, with every `.msg` text of `library` registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    types: dict[str, Any] = {}
    for name, text in library.ros_definitions().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return lambda data, ros_type: plain(store.deserialize_cdr(data, ros_type))


def mcap_ros2_decode(ros_type: str, schema: str, data: bytes) -> Any:
    """mcap_ros2's decoder of an MCAP `ros2msg` schema, as Foxglove and rosbag2 read one."""
    from mcap_ros2._dynamic import generate_dynamic

    return plain(generate_dynamic(ros_type, schema)[ros_type](data))


_NUMPY_TYPES = {"int8": "i1", "uint8": "u1", "int16": "<i2", "int32": "<i4", "int64": "<i8", "float32": "<f4",
                "float64": "<f8", "bool": "?", "byte": "u1", "char": "u1"}  # fmt: skip


def rosbags_writer(library: TypeLibrary) -> Callable[[Mapping[str, Any], str], bytes]:
    """rosbags' CDR serializer, with every `.msg` text of `library` registered: a message given
    as the dict `expected` makes (ROS names, flat arrays, nested dicts) to its CDR bytes."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    types: dict[str, Any] = {}
    for name, text in library.ros_definitions().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)

    def build(values: Mapping[str, Any], ros_type: str) -> Any:
        _, fields = store.fielddefs[ros_type]
        made: dict[str, Any] = {}
        for name, (node, details) in fields:
            value = values.get(name, 0)  # an empty message's one uint8
            if node in (3, 4):  # ARRAY, SEQUENCE
                (inner_node, inner), _ = details
                if inner_node == 1 and inner[0] != "string":
                    value = np.array(value, dtype=_NUMPY_TYPES[inner[0]])
                elif inner_node == 2:
                    value = [build(item, inner) for item in value]
            elif node == 2:
                value = build(value, details)
            made[name] = value
        return store.types[ros_type](**made)

    return lambda values, ros_type: bytes(store.serialize_cdr(build(values, ros_type), ros_type))


def arm_state(classes: Mapping[str, type]) -> Any:
    """An arm_state_t with something in every array, as lcm-gen's class."""
    point = classes["lab.geometry.point3d_t"]

    def at(x: float) -> Any:
        made = point()
        made.x, made.y, made.z, made.frameId = x, -x, 0.5, f"frame {x}"
        return made

    arm = classes["lab.robot.arm_state_t"]()
    arm.utime, arm.robotName, arm.numJoints, arm.rows, arm.cols = 7, "arm", 2, 2, 3
    arm.jointAngles, arm.gains = [0.5, 1.5], [1.0, 2.0, 3.0, 4.0]
    arm.grid = [[1, 2, 3], [4, 5, 6]]
    arm.table = [[1, 2]] * 4
    arm.cube = [[[1, 2, 3]] * 2] * 2
    arm.labels = [["a", "bé"], ["", "d"]]
    arm.blob, arm.fixedBlob, arm.flags, arm.enabled = b"xyz", b"\0\1\2", [True, False], True
    arm.tip, arm.waypoints, arm.corners = at(1), [at(2), at(3)], [[at(4), at(5)], [at(6), at(7)]]
    arm.tiny, arm.raw2d = [[1, -1], [2, -2]], [b"ab", b"cd"]
    arm.temperature, arm.mode, arm.lastValue = 21.5, 3, -1.0
    return arm
