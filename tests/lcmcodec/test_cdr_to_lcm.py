"""CDR -> LCM (`LcmType.from_cdr`), held to lcm-gen's encoder, with CDR from our own transcoder, from
rosbags' serializer and from rclpy's `serialize_message` (the built `drake_lcm_msgs`)."""

from __future__ import annotations

import contextlib
import struct
import tracemalloc
from collections.abc import Callable, Mapping
from typing import Any

import drake
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.lcmcodec.corpus import (
    CORPUS,
    TRANSLATOR_CORPUS,
    arm_state,
    assert_refused,
    expected,
    generate_lcmgen,
    lcmgen_messages,
    rosbags_writer,
)
from tests.lcmcodec.kept import assert_damage_agrees
from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.layout import LAYOUTS, MoveProgram
from viewer_bridge.lcmcodec.library import LcmType, TypeLibrary
from viewer_bridge.lcmcodec.schema import StructDef


def _structs(library: TypeLibrary) -> dict[str, StructDef]:
    return {known.full_name: known.definition for known in library.types()}


def _corpus_types(library: TypeLibrary) -> list[LcmType]:
    return [known for known in library.types() if known.source.startswith(str(CORPUS)) and known.ros_type]


def _drake_types(library: TypeLibrary) -> list[LcmType]:
    return [known for known in library.types() if known.full_name.startswith("drake.") and known.ros_type]


def _round_trips(known: LcmType, structs: Mapping[str, StructDef], classes: Mapping[str, type],
                 write: Callable[[Mapping[str, Any], str], bytes], examples: int) -> None:  # fmt: skip
    """lcm-gen's bytes -> to_cdr -> from_cdr are the same bytes; rosbags' CDR of the same values too."""
    assert known.ros_type is not None

    @settings(max_examples=examples, deadline=None, suppress_health_check=list(HealthCheck))
    @given(lcmgen_messages(known.definition, structs, classes))
    def check(message: Any) -> None:
        data = message.encode()
        assert known.from_cdr(known.to_cdr(data)) == data
        values = expected(type(message).decode(data), known.definition, structs)
        assert known.from_cdr(write(values, known.ros_type)) == data

    check()


def test_every_corpus_type_round_trips(library: TypeLibrary, classes: dict[str, type]) -> None:
    types = _corpus_types(library)
    assert len(types) == 5
    for known in types:
        _round_trips(known, _structs(library), classes, rosbags_writer(library), 40)


def test_the_translators_corpus_round_trips(tmp_path_factory: pytest.TempPathFactory) -> None:
    library = TypeLibrary.load([str(TRANSLATOR_CORPUS)], drake=False)
    classes = generate_lcmgen(tmp_path_factory.mktemp("translators_lcmgen"), TRANSLATOR_CORPUS)
    types = [k for k in library.types() if k.source.startswith(str(TRANSLATOR_CORPUS)) and k.ros_type]
    assert {k.full_name for k in types} == {"vbtest_geo.point3_t", "vbtest_lab.arm_status_t"}
    for known in types:
        _round_trips(known, _structs(library), classes, rosbags_writer(library), 30)


def test_every_drake_type_round_trips() -> None:
    library = TypeLibrary.load()
    classes = {known.full_name: getattr(drake, known.definition.name) for known in _drake_types(library)}
    types = _drake_types(library)
    assert "drake.lcmt_iiwa_command" in {known.full_name for known in types} and len(types) > 30
    write = rosbags_writer(library)
    for known in types:
        _round_trips(known, _structs(library), classes, write, 8)


def _iiwa_command(joints: int = 7, torques: int = 7) -> Any:
    message = drake.lcmt_iiwa_command()
    message.utime = 1_700_000_000_000_000
    message.num_joints, message.num_torques = joints, torques
    message.joint_position = [0.1 * joint - 0.3 for joint in range(joints)]
    message.joint_torque = [-2.5 * joint for joint in range(torques)]
    return message


@pytest.mark.parametrize(("joints", "torques"), [(7, 7), (7, 0), (0, 0), (1, 3)])
def test_rclpys_own_cdr_of_iiwa_command(joints: int, torques: int) -> None:
    """rclpy pads its messages to a multiple of 4 bytes; those bytes are not trailing garbage."""
    from drake_lcm_msgs.msg import LcmtIiwaCommand
    from rclpy.serialization import serialize_message

    message = _iiwa_command(joints, torques)
    ros = LcmtIiwaCommand(utime=message.utime, num_joints=joints, joint_position=message.joint_position,
                          num_torques=torques, joint_torque=message.joint_torque)  # fmt: skip
    known = TypeLibrary.load().for_ros_type("drake_lcm_msgs/msg/LcmtIiwaCommand")
    assert known is not None
    assert known.from_cdr(serialize_message(ros)) == message.encode()


def test_rclpys_own_cdr_of_robot_plan_strings_and_nesting() -> None:
    from drake_lcm_msgs.msg import LcmtRobotPlan, LcmtRobotState
    from rclpy.serialization import serialize_message

    plan, ros = drake.lcmt_robot_plan(), LcmtRobotPlan()
    plan.utime = ros.utime = 42
    for step in range(3):
        state = drake.lcmt_robot_state()
        state.utime, state.num_joints = step, 2
        state.joint_name = ["iiwa_joint_1", f"joint ü {step}"]
        state.joint_position = [step + 0.25, -step - 0.5]
        plan.plan.append(state)
        ros.plan.append(LcmtRobotState(utime=step, num_joints=2, joint_name=state.joint_name,
                                       joint_position=state.joint_position))  # fmt: skip
    plan.num_states = ros.num_states = 3
    assert TypeLibrary.load().get("drake.lcmt_robot_plan").from_cdr(serialize_message(ros)) == plan.encode()


def test_for_ros_type_takes_both_spellings(library: TypeLibrary) -> None:
    known = library.get("lab.robot.arm_state_t")
    assert library.for_ros_type("lab_robot_lcm_msgs/msg/ArmStateT") is known
    assert library.for_ros_type("lab_robot_lcm_msgs/ArmStateT") is known
    assert library.for_ros_type("lcm_msgs/PlainStatusT") is library.get("plain_status_t")
    assert library.for_ros_type("lab_robot_lcm_msgs/msg/TreeNodeT") is None  # refused: contains itself
    assert library.for_ros_type("std_msgs/msg/String") is None
    assert library.for_ros_type("nonsense") is None


# --- bad input ------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def iiwa() -> LcmType:
    return TypeLibrary.load().get("drake.lcmt_iiwa_command")


def _refused(known: LcmType, data: bytes, field: str, reason: str) -> DecodeError:
    return assert_refused(known.from_cdr, data, DecodeError, known, field, reason)


def test_every_truncation_and_extension_is_refused(iiwa: LcmType) -> None:
    cdr = iiwa.to_cdr(_iiwa_command(7, 7).encode())
    for end in range(len(cdr)):
        with pytest.raises(DecodeError, match="drake.lcmt_iiwa_command"):
            iiwa.from_cdr(cdr[:end])
    _refused(iiwa, cdr[:50], "joint_position", "count 7 needs at least 56 bytes, 30 remain")
    _refused(iiwa, cdr[:18], "joint_position", "truncated: needs 4 bytes, 2 remain")
    _refused(iiwa, cdr[:14], "num_joints", "truncated: needs 4 bytes, 2 remain")
    assert len(cdr) % 4 == 0
    error = _refused(iiwa, cdr + bytes(4), "<end>", "4 trailing bytes")
    assert error.offset == len(cdr) - 4
    _refused(iiwa, cdr + b"\0", "<end>", "1 trailing bytes")  # 1 byte makes no multiple of 4


def test_headers_other_than_little_endian_cdr_are_refused(iiwa: LcmType) -> None:
    cdr = iiwa.to_cdr(_iiwa_command().encode())
    _refused(iiwa, b"\x00\x00\x00\x00" + cdr[4:], "<header>", "big-endian CDR")
    _refused(iiwa, b"\x00\x07\x00\x00" + cdr[4:], "<header>", "representation 0007")
    _refused(iiwa, b"\x00\x01", "<header>", "truncated")


def test_a_sequence_must_hold_what_its_length_field_says(iiwa: LcmType) -> None:
    message = _iiwa_command(7, 7)
    message.num_joints = 6  # lcm-gen's class writes 7 elements anyway: the mismatch is in the CDR
    ros_like = struct.pack("<4sqi", b"\0\1\0\0", 1, 6) + struct.pack("<I7d", 7, *range(7))
    ros_like += struct.pack("<iI", 0, 0)
    error = _refused(iiwa, ros_like, "joint_position", "has 7 elements, but num_joints = 6")
    assert error.offset == 12
    bad_torques = (
        struct.pack("<4sqi", b"\0\1\0\0", 1, 1) + struct.pack("<Id", 1, 0.5) + struct.pack("<iI", 2, 1)
    )
    _refused(iiwa, bad_torques + bytes(8), "joint_torque", "has 1 elements, but num_torques = 2")
    negative = struct.pack("<4sqi", b"\0\1\0\0", 1, -1) + struct.pack("<I", 2**32 - 1)
    _refused(iiwa, negative, "joint_position", "length field num_joints is negative (-1)")


def _arm_cdr(library: TypeLibrary, classes: dict[str, type], **changes: Any) -> bytes:
    """The CDR of `_arm` with some ROS fields changed, written by rosbags (which checks nothing)."""
    known = library.get("lab.robot.arm_state_t")
    arm = arm_state(classes)
    values = expected(arm, known.definition, _structs(library))
    values.update(changes)
    return rosbags_writer(library)(values, "lab_robot_lcm_msgs/msg/ArmStateT")


def test_a_flattened_array_must_hold_the_product_of_its_dimensions(
    library: TypeLibrary, classes: dict[str, type]
) -> None:
    known = library.get("lab.robot.arm_state_t")
    assert known.from_cdr(_arm_cdr(library, classes)) == arm_state(classes).encode()
    grid = _arm_cdr(library, classes, grid=[1, 2, 3, 4, 5])
    _refused(known, grid, "grid", "has 5 elements, but rows × cols = 2 × 3 = 6")
    cube = _arm_cdr(library, classes, cube=[1] * 13)
    _refused(known, cube, "cube", "has 13 elements, but 2 × rows × 3 = 2 × 2 × 3 = 12")
    tiny = _arm_cdr(library, classes, tiny=[1, 2, 3])  # fixed dimensions only: still a sequence in ROS 2
    _refused(known, tiny, "tiny", "has 3 elements, but 2 × 2 = 2 × 2 = 4")
    labels = _arm_cdr(library, classes, labels=["a"] * 5)
    _refused(known, labels, "labels", "has 5 elements, but rows × 2 = 2 × 2 = 4")
    flags = _arm_cdr(library, classes, flags=[True])
    _refused(known, flags, "flags", "has 1 elements, but num_joints = 2")
    waypoints = _arm_cdr(library, classes, waypoints=[])
    _refused(known, waypoints, "waypoints", "has 0 elements, but num_joints = 2")


def test_every_array_sharing_one_length_is_checked(library: TypeLibrary, classes: dict[str, type]) -> None:
    """rows sizes grid, table, cube, labels and raw2d: each is held to it."""
    known = library.get("lab.robot.arm_state_t")
    for field, count in [("table", 4 * 3), ("raw2d", 3 * 2)]:
        data = _arm_cdr(library, classes, **{field: [1] * count})
        _refused(known, data, field, f"has {count} elements, but ")


def test_strings_and_bools_that_lcm_cannot_take(library: TypeLibrary, classes: dict[str, type]) -> None:
    known = library.get("lab.robot.arm_state_t")
    good = _arm_cdr(library, classes)
    name_at = 4 + 8  # robot_name's length after the header and utime
    assert good[name_at : name_at + 8] == b"\x04\0\0\0arm\0"
    inner_nul = good[:name_at] + b"\x04\0\0\0a\0m\0" + good[name_at + 8 :]
    assert classes["lab.robot.arm_state_t"].decode(known.from_cdr(inner_nul)).robotName == "a\0m"
    _refused(
        known, good[:name_at] + b"\x04\0\0\0a\xffm\0" + good[name_at + 8 :], "robot_name", "invalid UTF-8"
    )
    _refused(
        known, good[:name_at] + b"\x04\0\0\0armX" + good[name_at + 8 :], "robot_name", "not NUL-terminated"
    )
    _refused(known, good[:name_at] + b"\0\0\0\0" + good[name_at + 4 :], "robot_name", "length 0")
    nested = bytearray(_arm_cdr(library, classes, tip={"x": 1.0, "y": 2.0, "z": 3.0, "frame_id": "a?b"}))
    nested[nested.index(b"a?b") + 1] = 0xC3  # a UTF-8 lead byte with no continuation
    _refused(known, bytes(nested), "tip.frame_id", "invalid UTF-8")
    plain = library.get("plain_status_t")
    body = struct.pack("<qdB", 1, 2.0, 2)
    error = _refused(plain, b"\0\1\0\0" + body + bytes(64), "ok", "bool byte 2 is neither 0 nor 1")
    assert error.offset == 16
    flags = bytearray(_arm_cdr(library, classes, flags=[True, False]))
    index = bytes(flags).index(b"\x02\0\0\0\x01\x00") + 5  # the count 2, then True, False
    flags[index] = 9
    _refused(known, bytes(flags), "flags[1]", "bool byte 9")


def test_absurd_counts_are_refused_before_allocating(iiwa: LcmType) -> None:
    data = struct.pack("<4sqi", b"\0\1\0\0", 1, 2**31 - 1) + struct.pack("<I", 2**31 - 1) + bytes(64)
    tracemalloc.start()
    try:
        with pytest.raises(DecodeError, match="needs at least") as caught:
            iiwa.from_cdr(data)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert caught.value.field == "joint_position" and peak < 1_000_000


def test_a_refused_type_has_no_way_back(library: TypeLibrary) -> None:
    with pytest.raises(DecodeError, match="contains itself"):
        library.get("lab.robot.tree_node_t").from_cdr(b"\0\1\0\0")


def test_an_empty_message_reads_its_one_byte(tmp_path: Any) -> None:
    (tmp_path / "e.lcm").write_text(
        "package e; struct empty_t { } struct holder_t { e.empty_t a; int8_t b; }"
    )
    library = TypeLibrary.load([str(tmp_path / "e.lcm")], drake=False)
    known = library.get("e.holder_t")
    lcm = known.packed_fingerprint + b"\x05"
    assert known.to_cdr(lcm) == b"\0\1\0\0\0\5"
    assert known.from_cdr(b"\0\1\0\0\0\5") == lcm
    _refused(known, b"\0\1\0\0", "a.structure_needs_at_least_one_member", "truncated")


def test_memoryview_and_bytearray(iiwa: LcmType) -> None:
    data = _iiwa_command().encode()
    cdr = iiwa.to_cdr(data)
    assert iiwa.from_cdr(bytearray(cdr)) == iiwa.from_cdr(memoryview(b"xx" + cdr)[2:]) == data


_LIBRARY = TypeLibrary.load([str(CORPUS)], drake=False)


@given(st.binary(max_size=300))
@settings(max_examples=300, deadline=None)
def test_random_bytes_raise_only_decode_errors(data: bytes) -> None:
    for known in _corpus_types(_LIBRARY):
        with contextlib.suppress(DecodeError):
            lcm = known.from_cdr(b"\0\1\0\0" + data)
            assert known.from_cdr(known.to_cdr(lcm)) == lcm  # what is taken is a valid LCM message


# --- the kept layouts of messages of numbers only ------------------------------------------------------

MIX = """package mix;
struct mix_t { int8_t n; boolean flags[n]; float f[n]; int16_t m; int64_t big[m][2]; double d; boolean ok; }
"""


@pytest.mark.usefixtures("mover")
def test_a_kept_layout_takes_only_messages_of_its_own_shape() -> None:
    """(7, 7) and (6, 8) joints and torques give CDR of one size: the second must not be read
    with the first's layout; nor a message whose length field disagrees with its count."""
    iiwa = TypeLibrary.load().get("drake.lcmt_iiwa_command")  # its own: no layout the other mover learnt
    seven = iiwa.to_cdr(_iiwa_command(7, 7).encode())
    six = iiwa.to_cdr(_iiwa_command(6, 8).encode())
    assert len(seven) == len(six)
    assert iiwa.from_cdr(seven) == _iiwa_command(7, 7).encode()
    assert len(iiwa.encoder.layouts) == 1
    assert iiwa.from_cdr(six) == _iiwa_command(6, 8).encode()
    assert iiwa.from_cdr(seven) == _iiwa_command(7, 7).encode()
    lying = bytearray(seven)
    lying[4 + 8] = 6  # num_joints 6, seven positions
    _refused(iiwa, bytes(lying), "joint_position", "has 7 elements, but num_joints = 6")
    big_endian = b"\0\0" + seven[2:]
    _refused(iiwa, big_endian, "<header>", "big-endian")


@pytest.mark.usefixtures("mover")
def test_kept_layouts_agree_with_the_generated_code(tmp_path: Any) -> None:
    (tmp_path / "mix.lcm").write_text(MIX)
    known = TypeLibrary.load([str(tmp_path / "mix.lcm")], drake=False).get("mix.mix_t")
    lcm = known.packed_fingerprint + struct.pack(
        ">b2?2fh4qd?", 2, True, False, 0.5, -1.0, 2, 1, 2, 3, 4, 9.5, True
    )
    cdr = known.to_cdr(lcm)
    assert known.from_cdr(cdr) == lcm and known.encoder.layouts
    assert_damage_agrees(known.from_cdr, known.encoder.generated, cdr, changes=4, examples=400)
    flags = bytearray(cdr)
    flags[4 + 9] = 2  # after the header: n at 0, its count at 4..8, the flags at 8 and 9
    _refused(known, bytes(flags), "flags[1]", "bool byte 2")


def test_kept_layouts_of_strings_nesting_and_many_values_agree_with_the_generated_code(
    classes: dict[str, type], tmp_path: Any, mover: str
) -> None:
    """The same kept-layout mechanism takes every LCM type back from CDR: an arm_state_t (strings,
    bools, nested and multi-dimensional arrays: one unpack and one pack) and a message of more
    values than one `struct` takes (a gather of bytes), damaged anywhere, convert or fail as the
    generated code alone says."""
    arm = TypeLibrary.load([str(CORPUS)], drake=False).get("lab.robot.arm_state_t")  # its own: no layouts yet
    cdr = arm.to_cdr(arm_state(classes).encode())
    assert arm.from_cdr(cdr) == arm_state(classes).encode() and len(arm.encoder.layouts) == 1
    assert_damage_agrees(arm.from_cdr, arm.encoder.generated, cdr, changes=3, examples=300)
    assert list(arm.encoder.layouts) == [len(cdr)]
    (tmp_path / "wide.lcm").write_text(
        "package wide; struct wide_t { int16_t n; int64_t big[n]; float f[3]; }"
    )
    wide = TypeLibrary.load([str(tmp_path / "wide.lcm")], drake=False).get("wide.wide_t")
    lcm = wide.packed_fingerprint + struct.pack(">h300q3f", 300, *range(-150, 150), 0.5, -2.0, 1e9)
    cdr = wide.to_cdr(lcm)
    assert wide.from_cdr(cdr) == lcm == wide.from_cdr(cdr)
    found = wide.encoder.layouts[len(cdr)]
    # 304 values: gathered
    assert type(found) is MoveProgram if mover == "compiled" else found.gather is not None
    assert_damage_agrees(wide.from_cdr, wide.encoder.generated, cdr, changes=2, examples=200)


@pytest.mark.usefixtures("mover")
def test_kept_layouts_are_bounded_per_type(tmp_path: Any) -> None:
    """At most `LAYOUTS` sizes per type and direction; later sizes take the generated code, and
    give the same bytes."""
    (tmp_path / "b.lcm").write_text("package b; struct b_t { int32_t n; double v[n]; }")
    known = TypeLibrary.load([str(tmp_path / "b.lcm")], drake=False).get("b.b_t")
    messages = [known.packed_fingerprint + struct.pack(f">i{n}d", n, *range(n)) for n in range(LAYOUTS + 4)]
    for lcm in messages * 2:
        assert known.from_cdr(known.to_cdr(lcm)) == lcm
    assert len(known.encoder.layouts) == len(known.transcoder.layouts) == LAYOUTS


@pytest.mark.usefixtures("mover")
def test_float32_bits_are_carried_unchanged(tmp_path: Any) -> None:
    """A signalling NaN would come back quiet through a Python float: scalars, arrays and kept
    layouts, both ways, move a float32 as its bits."""
    (tmp_path / "f.lcm").write_text("package f; struct f_t { float a; int32_t n; float b[n]; }")
    known = TypeLibrary.load([str(tmp_path / "f.lcm")], drake=False).get("f.f_t")
    signalling = b"\x7f\xa0\x00\x01"
    lcm = known.packed_fingerprint + signalling + struct.pack(">i", 2) + signalling + b"\xff\x80\x00\x00"
    cdr = known.to_cdr(lcm)
    assert (
        cdr == b"\0\1\0\0" + signalling[::-1] + struct.pack("<iI", 2, 2) + signalling[::-1] + b"\0\0\x80\xff"
    )
    assert known.from_cdr(cdr) == lcm and known.encoder.layouts
    assert known.from_cdr(cdr) == lcm  # through the kept layout
