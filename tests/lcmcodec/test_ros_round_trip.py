"""ROS 2 CDR -> LCM (section 14) -> CDR by the way every LCM type goes to ROS 2 (section 13,
`LcmType.to_cdr`, what the `lcm_to_ros` translator publishes), over the standard types and a custom
one with bounded sequences, uint64, uint16/uint32 (widened), a non-ASCII string, nested arrays of
structs, constants and a wstring.

Section 13 gives the generated LCM struct its own ROS 2 type (`sensor_msgs_lcm_msgs/JointState`),
which has LCM's length fields as fields and the widened integers' wider types: its CDR is not the
original's bytes, by design (docs/PROTOCOLS.md section 14, "The way back"). What must hold, and is
asserted here: that CDR decodes to the original's values (each length field the length of its
sequence), and those values, written back as the original type, are the original CDR byte for byte.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
import pytest

from tests.lcmcodec.ros_bag import SAMPLES, typestore
from tests.lcmcodec.test_from_ros import CUSTOM
from tests.lcmcodec.test_ros_cdr import note_cdr, serialized
from viewer_bridge.lcmcodec.from_ros import LcmFromRos, RosField, load_ros_definitions, map_ros_types
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.lcmcodec.ros_cdr import compile_ros_encoders

TYPES = sorted({ros_type for _, ros_type, _ in SAMPLES} | {"my_robot/msg/Note"})
NUMBERS = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "uint8": np.uint8, "int8": np.int8,
           "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
           "uint64": np.uint64, "float32": np.float32, "float64": np.float64}  # fmt: skip


@pytest.fixture(scope="module")
def mapping() -> LcmFromRos:
    definitions, custom = load_ros_definitions([str(CUSTOM)])
    return map_ros_types(definitions, [*TYPES, *custom])


@pytest.fixture(scope="module")
def library(mapping: LcmFromRos, tmp_path_factory: pytest.TempPathFactory) -> TypeLibrary:
    """The generated `.lcm` files, as the bridge loads any LCM type."""
    folder = tmp_path_factory.mktemp("generated")
    mapping.write(folder)
    return TypeLibrary.load([str(folder)], drake=False)


@pytest.fixture(scope="module")
def section13_store(library: TypeLibrary) -> Any:
    """rosbags' store knowing section 13's ROS 2 types of the generated LCM structs."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    for ros_type, text in library.ros_definitions().items():
        store.register(get_types_from_msg(text, ros_type))
    return store


def back_to_ros(mapping: LcmFromRos, store: Any, ros_type: str, section13: Any) -> Any:
    """Section 13's message as the original ROS 2 type: each length field checked and dropped,
    each widened number narrowed back (it must fit: it came from the narrower type)."""
    values = {}
    for field in mapping.structs[ros_type].fields:
        value = getattr(section13, field.name)
        if field.kind == "sequence":
            assert getattr(section13, field.length_field) == len(value), field.name
        values[field.name] = _field_back(mapping, store, field, value)
    return store.types[ros_type](**values)


def _field_back(mapping: LcmFromRos, store: Any, field: RosField, value: Any) -> Any:
    if field.nested:
        if field.kind == "scalar":
            return back_to_ros(mapping, store, field.nested, value)
        return [back_to_ros(mapping, store, field.nested, item) for item in value]
    if field.base not in NUMBERS:
        return value  # strings (a wstring is a string in section 13)
    if field.kind == "scalar":
        narrowed = NUMBERS[field.base](value)
        assert int(narrowed) == int(value) if field.base not in ("float32", "float64") else True
        return narrowed.item() if field.base != "bool" else bool(value)
    array = np.asarray(value)
    narrowed = array.astype(NUMBERS[field.base])
    assert np.array_equal(narrowed, array), field.name  # nothing lost in the widening
    return narrowed


@pytest.mark.parametrize("index", range(len(SAMPLES)), ids=[ros_type for _, ros_type, _ in SAMPLES])
def test_cdr_to_lcm_to_section_13_cdr_holds_the_original_cdr_exactly(
    mapping: LcmFromRos, library: TypeLibrary, section13_store: Any, index: int
) -> None:
    _, ros_type, message = SAMPLES[index]
    store = typestore()
    original = serialized(ros_type, message)  # mcap-ros2-support's CDR, as the bag holds it
    lcm = compile_ros_encoders(mapping, [ros_type])[ros_type].encode(original)
    lcm_type = library.for_data(lcm)
    assert lcm_type is not None and lcm_type.ros_type is not None
    section13 = section13_store.deserialize_cdr(lcm_type.to_cdr(lcm), lcm_type.ros_type)
    rebuilt = back_to_ros(mapping, store, ros_type, section13)
    assert bytes(store.serialize_cdr(rebuilt, ros_type)) == original
    assert lcm_type.from_cdr(lcm_type.to_cdr(lcm)) == lcm  # and LCM -> CDR -> LCM is the identity


def test_the_original_types_cdr_differs_from_section_13s_by_the_length_fields(
    mapping: LcmFromRos, library: TypeLibrary
) -> None:
    """Why bytes cannot be compared: JointState's section 13 CDR has an int32 length before each
    sequence; removing them (and the padding they move) gives the original back."""
    joints = next(message for _, ros_type, message in SAMPLES if ros_type == "sensor_msgs/msg/JointState")
    original = serialized("sensor_msgs/msg/JointState", {**joints, "name": ["a"], "velocity": [0.5]})
    lcm = compile_ros_encoders(mapping, ["sensor_msgs/msg/JointState"])["sensor_msgs/msg/JointState"].encode(
        original
    )
    lcm_type = library.for_data(lcm)
    assert lcm_type is not None
    section13 = lcm_type.to_cdr(lcm)
    assert section13 != original and len(section13) > len(original)
    assert struct.pack("<iI", 1, 1) in section13  # name_length = 1, then name's own count 1


def test_a_wstring_comes_back_as_the_same_text(
    mapping: LcmFromRos, library: TypeLibrary, section13_store: Any
) -> None:
    """Neither rosbags nor mcap-ros2-support writes a wstring, so the CDR is Fast DDS's by hand;
    section 13 has it as a string: the text is the same (UTF-16 -> UTF-8 loses nothing)."""
    lcm = compile_ros_encoders(mapping, ["my_robot/msg/Note"])["my_robot/msg/Note"].encode(note_cdr())
    lcm_type = library.for_data(lcm)
    assert lcm_type is not None and lcm_type.ros_type is not None
    section13 = section13_store.deserialize_cdr(lcm_type.to_cdr(lcm), lcm_type.ros_type)
    assert (section13.text, section13.note, section13.more_length, section13.more) == ("hi", "hé", 1, ["😀"])


def test_constants_are_carried_where_lcm_has_them(library: TypeLibrary, section13_store: Any) -> None:
    """A constant goes to LCM as a const of the member's type (a byte one widened to int16_t) and
    from there into section 13's type; one LCM cannot hold (a string, a uint64 from 2^63) does not."""
    gripper = library.get("my_robot.Gripper")
    assert gripper.ros_type is not None
    ros = section13_store.types[gripper.ros_type]
    assert (ros.MODE_OPEN, ros.ENABLED, ros.HALF) == (1, 1, 0.5)
    assert not hasattr(ros, "BIG") and not hasattr(ros, "GREETING")
