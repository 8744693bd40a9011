"""ROS 2 CDR -> LCM for mapped ROS 2 types (docs/PROTOCOLS.md section 14), held to lcm-gen's own
Python decoding what the bridge wrote, message by message, against the bag's values."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import pytest

from tests.lcmcodec.kept import assert_damage_agrees
from tests.lcmcodec.ros_bag import SAMPLES, lcmgen_decode, typestore, write_bag
from tests.lcmcodec.test_from_ros import CUSTOM, lcm_gen_all
from tests.optional import peer
from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.cdr_to_lcm import LcmEncoder
from viewer_bridge.lcmcodec.from_ros import LcmFromRos, load_ros_definitions, map_ros_types
from viewer_bridge.lcmcodec.layout import MoveProgram
from viewer_bridge.lcmcodec.ros_cdr import compile_ros_encoders

TYPES = sorted({ros_type for _, ros_type, _ in SAMPLES} | {"std_msgs/msg/Bool", "my_robot/msg/Note"})


@pytest.fixture(scope="module")
def mapping() -> LcmFromRos:
    definitions, custom = load_ros_definitions([str(CUSTOM)])
    return map_ros_types(definitions, [*TYPES, *custom])


@pytest.fixture(scope="module")
def encoders(mapping: LcmFromRos) -> dict[str, LcmEncoder]:
    return compile_ros_encoders(mapping, TYPES)


@pytest.fixture(scope="module")
def lcmgen_python(mapping: LcmFromRos, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("ros_lcm")
    mapping.write(folder / "lcm")
    assert lcm_gen_all(folder / "lcm", folder / "gen").returncode == 0
    return folder / "gen" / "py"


def as_lcm(mapping: LcmFromRos, ros_type: str, message: Any) -> dict[str, Any]:
    """A decoded ROS 2 message as the LCM struct holds it: its fields, and each sequence's length."""
    found: dict[str, Any] = {}
    for field in mapping.structs[ros_type].fields:
        value = getattr(message, field.name)
        if field.kind == "sequence":
            found[field.length_field] = len(value)
        if field.nested:
            value = as_lcm(mapping, field.nested, value) if field.kind == "scalar" else [
                as_lcm(mapping, field.nested, item) for item in value]  # fmt: skip
        elif field.kind != "scalar" and not isinstance(value, bytes):
            value = list(value)
        found[field.name] = value
    return found


def test_every_message_of_a_bag_decodes_in_lcm_gens_python_to_the_bags_values(
    tmp_path: Path, mapping: LcmFromRos, encoders: dict[str, LcmEncoder], lcmgen_python: Path
) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    write_bag(tmp_path / "bag.mcap")
    expected, converted = [], []
    with (tmp_path / "bag.mcap").open("rb") as stream:
        for schema, _, message, decoded in make_reader(
            stream, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages():
            assert schema is not None
            expected.append(as_lcm(mapping, schema.name, decoded))
            converted.append(
                (mapping.structs[schema.name].lcm_name, encoders[schema.name].encode(message.data))
            )
    assert len(converted) == len(SAMPLES)
    assert lcmgen_decode(lcmgen_python, converted) == expected
    # widened, kept
    assert expected[-1]["serial"] == (1 << 63) - 1 and expected[-1]["fingers"][0]["id"] == 65535


def test_wstrings_arrive_as_utf8(
    mapping: LcmFromRos, encoders: dict[str, LcmEncoder], lcmgen_python: Path
) -> None:
    [message] = lcmgen_decode(
        lcmgen_python, [("my_robot.Note", encoders["my_robot/msg/Note"].encode(note_cdr()))]
    )
    assert message == {"text": "hi", "note": "hé", "more_length": 1, "more": ["😀"]}


def note_cdr(units: tuple[int, ...] = (0xD83D, 0xDE00)) -> bytes:
    """my_robot/Note as Fast DDS writes it: wstrings as a count of UTF-16 units, each in 4 bytes."""
    return (b"\x00\x01\x00\x00" + struct.pack("<I3sx", 3, b"hi\0") + struct.pack("<3I", 2, ord("h"), ord("é"))
            + struct.pack("<II", 1, len(units)) + struct.pack(f"<{len(units)}I", *units))  # fmt: skip


def serialized(ros_type: str, message: dict[str, Any]) -> bytes:
    """The CDR of `message` (nested dicts) by mcap-ros2-support's serializer, as the bag holds it."""
    from mcap_ros2._dynamic import serialize_dynamic

    encoder = serialize_dynamic(ros_type, typestore().generate_msgdef(ros_type, ros_version=2)[0])[ros_type]
    return bytes(encoder(message))


JOINTS = next(message for _, ros_type, message in SAMPLES if ros_type == "sensor_msgs/msg/JointState")
GRIPPER = next(message for _, ros_type, message in SAMPLES if ros_type == "my_robot/msg/Gripper")


def test_rosbags_cdr_converts_too(encoders: dict[str, LcmEncoder], lcmgen_python: Path) -> None:
    """A second CDR writer, with an empty sequence between full ones (aligned only when not empty)."""
    import numpy as np

    store = typestore()
    types = store.types
    message = types["sensor_msgs/msg/JointState"](
        header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=-3, nanosec=5), frame_id="x"),
        name=["a"], position=np.array([], np.float64), velocity=np.array([0.25]), effort=np.array([-1.0, 2.0]),
    )  # fmt: skip
    data = bytes(store.serialize_cdr(message, "sensor_msgs/msg/JointState"))
    lcm = encoders["sensor_msgs/msg/JointState"].encode(data)
    [decoded] = lcmgen_decode(lcmgen_python, [("sensor_msgs.JointState", lcm)])
    assert decoded["header"] == {"stamp": {"sec": -3, "nanosec": 5}, "frame_id": "x"}
    assert (decoded["name"], decoded["position"], decoded["velocity"], decoded["effort"]) == (
        ["a"],
        [],
        [0.25],
        [-1.0, 2.0],
    )
    assert decoded["position_length"] == 0 and decoded["effort_length"] == 2


def swapped(data: bytes, old: bytes, new: bytes) -> bytes:
    """`data` with the first `old` (which must be there) replaced by `new`."""
    assert old in data
    return data.replace(old, new, 1)


@pytest.mark.parametrize(
    ("ros_type", "damage", "field", "reason"),
    [
        ("sensor_msgs/msg/JointState", lambda d: d[:-1], "effort", "24 bytes, 23 remain"),
        ("sensor_msgs/msg/JointState", lambda d: d + bytes(8), "<end>", "trailing bytes"),
        ("sensor_msgs/msg/JointState", lambda d: swapped(d, b"base_link", b"base\xfflink"), "header.frame_id", "UTF-8"),
        ("sensor_msgs/msg/JointState", lambda d: swapped(d, struct.pack("<I", 3) + struct.pack("<I", 9),
                                                          struct.pack("<I", 0x7FFFFFF0) + struct.pack("<I", 9)),
         "name", "count 2147483632 needs"),
        ("sensor_msgs/msg/JointState", lambda d: swapped(d, struct.pack("<I", 3) + struct.pack("<I", 9),
                                                          struct.pack("<I", 0xFFFFFFFF) + struct.pack("<I", 9)),
         "name", "int32_t length field"),
        ("sensor_msgs/msg/JointState", lambda d: b"\x00\x00" + d[2:], "<header>", "big-endian"),
        ("sensor_msgs/msg/JointState", lambda d: swapped(d, b"elbow\0", b"elb\xffw\0"), "name[1]", "UTF-8"),
        ("sensor_msgs/msg/JointState", lambda d: swapped(d, b"elbow\0", b"elbow!"), "name[1]", "NUL"),
        ("sensor_msgs/msg/JointState", lambda d: swapped(d, b"\x06\0\0\0elbow", b"\0\0\0\0elbow"), "name[1]", "length 0"),
        ("my_robot/msg/Gripper", lambda d: swapped(d, struct.pack("<q", (1 << 63) - 1), struct.pack("<Q", 1 << 63)),
         "serial", "uint64 9223372036854775808"),
        ("my_robot/msg/Gripper", lambda d: swapped(d, b"\x03\x00\x00\x00\x01\x00\x01", b"\x03\x00\x00\x00\x01\x00\x02"),
         "flags[2]", "bool byte 2"),
        ("my_robot/msg/Gripper", lambda d: swapped(d, struct.pack("<I3h", 3, -32768, 0, 32767),
                                                   struct.pack("<I3h", 5, -32768, 0, 32767)), "torques", "bound 4"),
        ("my_robot/msg/Gripper", lambda d: swapped(d, b"index\0", b"ind\xc3\0\0"), "fingers[0].name", "UTF-8"),
    ],
)  # fmt: skip
def test_bad_cdr_is_a_decode_error_naming_the_field(
    encoders: dict[str, LcmEncoder], ros_type: str, damage: Any, field: str, reason: str
) -> None:
    data = serialized(ros_type, JOINTS if ros_type.startswith("sensor") else GRIPPER)
    encoders[ros_type].encode(data)  # its layout is kept: a damaged message of its size meets it first
    with pytest.raises(DecodeError) as caught:
        encoders[ros_type].encode(damage(data))
    assert caught.value.field == field and reason in caught.value.reason, caught.value


@pytest.mark.usefixtures("mover")
@pytest.mark.parametrize("ros_type", ["sensor_msgs/msg/JointState", "my_robot/msg/Gripper"])
def test_kept_layouts_agree_with_the_generated_code(mapping: LcmFromRos, ros_type: str) -> None:
    """A message of a kept layout's size, its bytes changed anywhere (counts, lengths, NULs, bools,
    a uint64's top bit, a string's UTF-8), converts or fails as the generated code alone says."""
    data = serialized(ros_type, JOINTS if ros_type.startswith("sensor") else GRIPPER)
    [kept] = compile_ros_encoders(mapping, [ros_type]).values()
    assert kept.encode(data) == kept.encode(data) and len(kept.layouts) == 1
    generated = compile_ros_encoders(mapping, [ros_type], keep_layouts=False)[ros_type]
    assert_damage_agrees(kept.encode, generated.encode, data, changes=3, examples=300)
    assert len(kept.layouts) == 1  # every message of that size met the kept layout first


def test_kept_layouts_of_many_widened_values_agree_with_the_generated_code(mover: str) -> None:
    """More values than one `struct` takes are gathered as bytes: uint16 and uint32 widened to
    LCM's int32_t and int64_t (zeros before the reversed bytes), a string, counts as length
    fields; damaged anywhere, the message converts or fails as the generated code alone says."""
    ros_type = "std_msgs/msg/UInt16MultiArray"
    definitions, _ = load_ros_definitions([])
    mapping = map_ros_types(definitions, [ros_type])
    layout = {"dim": [{"label": "rows", "size": 3, "stride": 4_000_000_000}], "data_offset": 65_000}
    data = serialized(ros_type, {"layout": layout, "data": [i * 217 % 65_536 for i in range(300)]})
    [kept] = compile_ros_encoders(mapping, [ros_type]).values()
    generated = compile_ros_encoders(mapping, [ros_type], keep_layouts=False)[ros_type]
    assert kept.encode(data) == kept.encode(data) == generated.encode(data)
    found = kept.layouts[len(data)]
    assert (
        type(found) is MoveProgram if mover == "compiled" else found is not None and found.gather is not None
    )
    assert_damage_agrees(kept.encode, generated.encode, data, changes=3, examples=200)


def test_bad_bools_scalars_and_wstrings_are_decode_errors(encoders: dict[str, LcmEncoder]) -> None:
    with pytest.raises(DecodeError, match=r"std_msgs/msg/Bool\.data at byte 0: bool byte 2"):
        encoders["std_msgs/msg/Bool"].encode(b"\x00\x01\x00\x00\x02")
    with pytest.raises(DecodeError, match=r"more\[0\] at byte 28: code unit 0x110000 is not UTF-16"):
        encoders["my_robot/msg/Note"].encode(note_cdr((0x110000,)))
    with pytest.raises(DecodeError, match=r"more\[0\] at byte \d+: invalid UTF-16 \(unpaired surrogate\)"):
        encoders["my_robot/msg/Note"].encode(note_cdr((0xD83D, 0x41)))
    with pytest.raises(DecodeError, match=r"more\[0\] at byte \d+: count 1 needs at least 4 bytes, 0 remain"):
        encoders["my_robot/msg/Note"].encode(note_cdr(())[:-4] + struct.pack("<I", 1))


rclpy_serialization = peer("rclpy.serialization")
ros_sensor_msgs = peer("sensor_msgs.msg")


def test_rclpy_cdr_gives_the_same_lcm_bytes(encoders: dict[str, LcmEncoder]) -> None:
    """ROS 2's own serializer (which pads a message to 4 bytes) against mcap-ros2-support's. No
    sequence of 8-byte numbers is empty: rclpy's `serialize_message` then reports 4 bytes more per
    such sequence than it writes (its size estimate), which are refused as trailing bytes."""
    message = ros_sensor_msgs.JointState(name=JOINTS["name"], position=JOINTS["position"], velocity=[0.5, 0.25, 0.0],
                                         effort=JOINTS["effort"])  # fmt: skip
    message.header.stamp.sec, message.header.stamp.nanosec = 1_700_000_000, 123_456_789
    message.header.frame_id = "base_link"
    image = ros_sensor_msgs.Image(height=1, width=3, encoding="mono8", step=3, data=b"\x01\x02\x03")
    for ros_type, ros_message, values in [
        ("sensor_msgs/msg/JointState", message, {**JOINTS, "velocity": [0.5, 0.25, 0.0]}),
        ("sensor_msgs/msg/Image", image, {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}, "height": 1,
                                          "width": 3, "encoding": "mono8", "is_bigendian": 0, "step": 3,
                                          "data": b"\x01\x02\x03"}),
    ]:  # fmt: skip
        ours = encoders[ros_type].encode(rclpy_serialization.serialize_message(ros_message))
        assert ours == encoders[ros_type].encode(serialized(ros_type, values))


_HUGE = 0x7FFFFFFF
_EMPTY_HEADER = b"\x00\x01\x00\x00" + struct.pack("<iII", 1, 2, 1) + b"\0\0\0\0"  # stamp, frame_id ""


@pytest.mark.parametrize(
    ("ros_type", "cdr", "field"),
    [
        ("sensor_msgs/msg/JointState", _EMPTY_HEADER + struct.pack("<I", _HUGE), "name"),
        ("sensor_msgs/msg/JointState", _EMPTY_HEADER + struct.pack("<II", 0, _HUGE) + bytes(16), "position"),
        ("my_robot/msg/Note", b"\x00\x01\x00\x00" + struct.pack("<I3sxI", 3, b"hi\0", _HUGE) + bytes(8), "note"),
        ("my_robot/msg/Note", b"\x00\x01\x00\x00" + struct.pack("<I3sxIII", 3, b"hi\0", 0, _HUGE, 1), "more"),
    ],
)  # fmt: skip
def test_a_count_of_2_31_elements_is_refused_before_anything_is_allocated(
    encoders: dict[str, LcmEncoder], ros_type: str, cdr: bytes, field: str
) -> None:
    import tracemalloc

    tracemalloc.start()
    try:
        with pytest.raises(DecodeError) as caught:
            encoders[ros_type].encode(cdr)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert caught.value.field == field and "2147483647" in caught.value.reason, caught.value
    assert peak < 1 << 20


def _pose() -> Any:
    from viewer_bridge.formats.ros.messages import make

    return make("geometry_msgs/msg/Pose", position=make("geometry_msgs/msg/Point", x=1.0, y=-2.0, z=3.5),
                orientation=make("geometry_msgs/msg/Quaternion", w=1.0))  # fmt: skip


@pytest.mark.parametrize(
    ("ros_type", "values"),
    [
        ("geometry_msgs/msg/Pose", None),
        ("std_msgs/msg/String", {"data": "héllo"}),
        ("std_msgs/msg/Bool", {"data": True}),
    ],
)
def test_one_generator_both_mappings_give_the_same_lcm_bytes_and_errors(
    ros_type: str, values: dict[str, Any] | None
) -> None:
    """A ROS 2 type with no sequence and no unsigned integer maps onto an LCM struct whose own ROS 2
    form is the type itself: the ROS 2 mapping and the LCM types' one (`lcm_wire`) give the one
    generator the same wire fields, so the same LCM bytes and the same errors."""
    from viewer_bridge.formats.ros.messages import make, to_cdr
    from viewer_bridge.lcmcodec.cdr_to_lcm import compile_encoders, lcm_wire

    mapping = map_ros_types(load_ros_definitions([ros_type])[0], [ros_type])
    lcm_name = mapping.structs[ros_type].lcm_name
    fields = [(f.name, f.base, f.kind, f.count) for f in lcm_wire(mapping.lcm)[lcm_name].fields]
    # an LCM byte is ROS 2's byte, which the mapping writes as uint8 (the same wire)
    assert fields == [(f.name, f.base, f.kind, f.count) for f in mapping.structs[ros_type].fields]
    cdr = to_cdr(_pose() if values is None else make(ros_type, **values))
    ros = compile_ros_encoders(mapping, [ros_type], keep_layouts=False)[ros_type]
    fingerprints = {s.lcm_name: mapping.packed_fingerprint(s.ros_name) for s in mapping.structs.values()}
    lcm = compile_encoders(mapping.lcm, fingerprints, [lcm_name])[lcm_name]
    assert ros.encode(cdr) == lcm.encode(cdr) == lcm.encode(cdr)  # the second: its kept layout
    for cut in (4, len(cdr) - 1):
        with pytest.raises(DecodeError) as by_ros:
            ros.encode(cdr[:cut])
        with pytest.raises(DecodeError) as by_lcm:
            lcm.encode(cdr[:cut])
        assert (by_ros.value.field, by_ros.value.offset, by_ros.value.reason) == (
            by_lcm.value.field, by_lcm.value.offset, by_lcm.value.reason)  # fmt: skip
