"""The compiled LCM -> CDR transcoder, held to lcm-gen's encoder and two independent CDR readers."""

from __future__ import annotations

import contextlib
import struct
import tracemalloc
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import drake
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.lcmcodec.corpus import (
    CORPUS,
    PLAIN_TAIL,
    arm_state,
    expected,
    lcmgen_messages,
    mcap_ros2_decode,
    rosbags_reader,
)
from tests.lcmcodec.kept import assert_damage_agrees
from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.cdr import CdrTranscoder, compile_transcoders
from viewer_bridge.lcmcodec.library import TypeLibrary

CDR_TYPES = [
    "lab.geometry.point3d_t",
    "lab.robot.arm_state_t",
    "lab.robot.heartbeat_t",
    "lab.robot.pulse_t",
    "plain_status_t",
]


@pytest.fixture(scope="module")
def read_cdr(library: TypeLibrary) -> Callable[[bytes, str], Any]:
    return rosbags_reader(library)


def test_the_corpus_types_that_ros_can_say_are_the_ones_transcoded(library: TypeLibrary) -> None:
    corpus = [known for known in library.types() if known.source.startswith(str(CORPUS))]
    assert sorted(known.full_name for known in corpus if known.ros_type) == CDR_TYPES


@pytest.mark.parametrize("type_name", CDR_TYPES)
def test_every_value_survives_as_independent_readers_decode_it(
    type_name: str, library: TypeLibrary, classes: dict[str, type], read_cdr: Callable[[bytes, str], Any]
) -> None:
    known = library.get(type_name)
    structs = {t.full_name: t.definition for t in library.types()}
    assert known.ros_type is not None

    @settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
    @given(lcmgen_messages(known.definition, structs, classes))
    def check(message: Any) -> None:
        data = message.encode()
        want = expected(type(message).decode(data), known.definition, structs)
        cdr = known.to_cdr(data)
        assert read_cdr(cdr, known.ros_type) == want
        assert mcap_ros2_decode(known.ros_type, known.ros2msg, cdr) == want

    check()


def _iiwa_status(joints: int) -> Any:
    message = drake.lcmt_iiwa_status()
    message.utime = 123_456_789
    message.num_joints = joints
    for number, name in enumerate(message.__slots__[2:]):
        setattr(message, name, [number * 10.0 + joint / 7 for joint in range(joints)])
    return message


def _robot_plan() -> Any:
    plan = drake.lcmt_robot_plan()
    plan.utime = 42
    for step in range(3):
        state = drake.lcmt_robot_state()
        state.utime = step
        state.num_joints = 2
        state.joint_name = ["iiwa_joint_1", "iiwa_joint_2 ü"]
        state.joint_position = [step + 0.25, -step - 0.5]
        plan.plan.append(state)
    plan.num_states = len(plan.plan)
    return plan


@pytest.mark.parametrize(
    "message", [_iiwa_status(7), _iiwa_status(0), _robot_plan()], ids=["iiwa7", "iiwa0", "plan"]
)
def test_drakes_own_types_from_pydrakes_classes(message: Any, read_cdr: Callable[[bytes, str], Any]) -> None:
    library = TypeLibrary.load()  # Drake's module is loaded by default
    data = message.encode()
    known = library.for_data(data)
    # The project ships these types' `.lcm` files too (lcmtypes/): either source, one fingerprint.
    assert known is not None and known.packed_fingerprint == type(message)._get_packed_fingerprint()
    assert known.ros_type
    structs = {t.full_name: t.definition for t in library.types()}
    want = expected(type(message).decode(data), known.definition, structs)
    cdr = known.to_cdr(data)
    assert rosbags_reader(library)(cdr, known.ros_type) == want
    assert mcap_ros2_decode(known.ros_type, known.ros2msg, cdr) == want


def test_drake_iiwa_status_layout_by_hand(library: TypeLibrary) -> None:
    """The bytes themselves, written out: header, scalars, then count / padding / doubles."""
    cdr = TypeLibrary.load().get("drake.lcmt_iiwa_status").to_cdr(_iiwa_status(1).encode())
    header, utime, joints = struct.unpack_from("<4sqi", cdr)
    assert (header, utime, joints) == (b"\x00\x01\x00\x00", 123_456_789, 1)
    # utime 0..8, num_joints 8..12; first count 12..16, its double 16..24 (8-aligned); the next
    # count 24..28, padding 28..32, the double 32..40 ...
    assert struct.unpack_from("<Id", cdr, 4 + 12) == (1, 0.0)
    assert struct.unpack_from("<I4xd", cdr, 4 + 24) == (1, 10.0)
    assert len(cdr) == 4 + 12 + 12 + 6 * 16


# --- bad input ------------------------------------------------------------------------------------


def test_every_truncation_and_extension_is_a_decode_error(
    library: TypeLibrary, classes: dict[str, type]
) -> None:
    known = library.get("lab.robot.arm_state_t")
    data = arm_state(classes).encode()
    for end in range(len(data)):
        with pytest.raises(DecodeError, match="lab.robot.arm_state_t"):
            known.to_cdr(data[:end])
    with pytest.raises(DecodeError, match="1 trailing bytes") as caught:
        known.to_cdr(data + b"\0")
    assert caught.value.offset == len(data)


def test_a_wrong_fingerprint_names_both(library: TypeLibrary) -> None:
    known = library.get("lab.geometry.point3d_t")
    with pytest.raises(DecodeError, match="fingerprint") as caught:
        known.to_cdr(bytes(8) + bytes(24) + b"\0\0\0\1\0")
    assert caught.value.field == "<fingerprint>" and known.packed_fingerprint.hex() in str(caught.value)


@pytest.mark.parametrize("count", [2**31 - 1, -1, -(2**31)])
def test_absurd_and_negative_lengths_are_refused_before_allocating(library: TypeLibrary, count: int) -> None:
    known = library.get("plain_status_t")
    body = (
        struct.pack(">qd?", 1, 2.0, True)
        + struct.pack(">dddI", 0, 0, 0, 1)
        + b"\0"
        + struct.pack(">i", count)
    )
    tracemalloc.start()
    try:
        with pytest.raises(DecodeError) as caught:
            known.to_cdr(known.packed_fingerprint + body + bytes(64))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert caught.value.field == "samples" and caught.value.offset == 8 + len(body)
    assert str(count) in str(caught.value)
    assert peak < 1_000_000


def test_a_nested_error_names_the_field_path(library: TypeLibrary) -> None:
    known = library.get("plain_status_t")
    bad_string = struct.pack(">qd?", 1, 2.0, True) + struct.pack(">dddI", 0, 0, 0, 2) + b"\xff\0" + bytes(4)
    with pytest.raises(DecodeError, match="invalid UTF-8") as caught:
        known.to_cdr(known.packed_fingerprint + bad_string)
    assert caught.value.field == "where.frameId" and caught.value.offset == 8 + 17 + 24 + 4


def test_booleans_other_than_one_are_true(
    library: TypeLibrary, read_cdr: Callable[[bytes, str], Any]
) -> None:
    known = library.get("plain_status_t")
    body = struct.pack(">qdB", 1, 2.0, 7) + struct.pack(">dddI", 0, 0, 0, 1) + b"\0" + struct.pack(">i", 0)
    body += PLAIN_TAIL
    read = read_cdr(known.to_cdr(known.packed_fingerprint + body), "lcm_msgs/msg/PlainStatusT")
    assert read["ok"] is True and read["bits"] == [False, True, True]
    assert (read["tags"], read["odd"], read["fixed_shorts"], read["fixed_longs"]) == (
        ["a", ""],
        -1,
        [1, -2, 3],
        [5, -6],
    )


def test_a_refused_type_has_no_cdr(library: TypeLibrary) -> None:
    known = library.get("lab.robot.tree_node_t")
    with pytest.raises(DecodeError, match="contains itself"):
        known.to_cdr(known.packed_fingerprint)


@given(st.binary(max_size=200))
@settings(max_examples=300, deadline=None)
def test_random_bytes_raise_only_decode_errors(data: bytes) -> None:
    library = _LIBRARY
    for name in CDR_TYPES:
        known = library.get(name)
        with contextlib.suppress(DecodeError):
            known.to_cdr(known.packed_fingerprint + data)


_LIBRARY = TypeLibrary.load([str(CORPUS)], drake=False)


def test_path_of_corpus_is_outside_lcmtypes() -> None:
    assert Path("lcmtypes") not in CORPUS.parents


def test_bytes_bytearray_and_memoryview_give_the_same_cdr(
    library: TypeLibrary, classes: dict[str, type], read_cdr: Callable[[bytes, str], Any]
) -> None:
    """Small bytes are sliced directly, everything else through a view: both ways, small and large."""
    known = library.get("lab.robot.arm_state_t")
    small = arm_state(classes).encode()
    arm = classes["lab.robot.arm_state_t"].decode(small)
    arm.cols, arm.rows = 3000, 2
    arm.grid = [list(range(3000)), list(range(3000, 6000))]
    arm.table, arm.cube = [[1, 2]] * 4, [[[1, 2, 3]] * 2] * 2
    arm.labels, arm.raw2d, arm.blob = [["x" * 300, "y"], ["", "z"]], [b"ab", b"cd"], bytes(range(250)) * 12
    large = arm.encode()
    assert len(large) > 8192
    for data in (small, large):
        cdr = known.to_cdr(data)
        assert known.to_cdr(bytearray(data)) == known.to_cdr(memoryview(data)) == cdr
        assert known.to_cdr(memoryview(b"pad" + data)[3:]) == cdr
    structs = {t.full_name: t.definition for t in library.types()}
    assert read_cdr(known.to_cdr(large), "lab_robot_lcm_msgs/msg/ArmStateT") == expected(
        type(arm).decode(large), known.definition, structs
    )


# --- kept layouts: the fast path -----------------------------------------------------------------


def _transcoders(library: TypeLibrary, name: str) -> tuple[CdrTranscoder, CdrTranscoder]:
    """The transcoder of `name` that keeps layouts, and one that only runs the generated code."""
    closure = library.closure(name)
    fingerprints = {each: library.get(each).packed_fingerprint for each in closure}
    kept = compile_transcoders(closure, fingerprints, [name])[name]
    return kept, compile_transcoders(closure, fingerprints, [name], keep_layouts=False)[name]


@pytest.mark.usefixtures("mover")
@pytest.mark.parametrize("type_name", CDR_TYPES)
def test_kept_layouts_give_the_generated_codes_bytes(
    type_name: str, library: TypeLibrary, classes: dict[str, type]
) -> None:
    """Every message twice: the first teaches its layout, the second takes it; both are the
    generated code's bytes, byte for byte."""
    kept, generated = _transcoders(library, type_name)
    structs = {t.full_name: t.definition for t in library.types()}

    @settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
    @given(lcmgen_messages(library.get(type_name).definition, structs, classes))
    def check(message: Any) -> None:
        data = message.encode()
        want = generated.transcode(data)
        assert kept.transcode(data) == want
        assert kept.transcode(data) == want
        assert len(data) in kept.layouts or len(kept.layouts) == 16

    check()


@pytest.mark.usefixtures("mover")
def test_kept_layouts_agree_with_the_generated_code(library: TypeLibrary, classes: dict[str, type]) -> None:
    """An arm_state_t (strings, bools, nested and multi-dimensional arrays) of a kept layout's
    size, its bytes changed anywhere (lengths, NULs, UTF-8, bools, numbers), converts or fails as
    the generated code alone says."""
    kept, generated = _transcoders(library, "lab.robot.arm_state_t")
    data = arm_state(classes).encode()
    assert kept.transcode(data) == generated.transcode(data) and len(kept.layouts) == 1
    assert kept.layouts[len(data)] is not None  # bools among sequences: gathered, then made 0 or 1

    assert_damage_agrees(kept.transcode, generated.transcode, data, changes=3, examples=400)
    assert len(kept.layouts) == 1  # every message of that size met the kept layout first


@pytest.mark.usefixtures("mover")
def test_a_kept_layout_takes_only_messages_of_its_own_shape(
    library: TypeLibrary, classes: dict[str, type]
) -> None:
    """Two strings of lengths (1, 3) and (3, 1) make messages of one size: the second must not be
    read with the first's layout; nor a bool byte 2 be copied as 2, nor a string become bad UTF-8."""
    kept, generated = _transcoders(library, "lab.robot.arm_state_t")
    arm = arm_state(classes)
    arm.robotName, arm.labels = "a", [["abc", "bé"], ["", "d"]]
    first = arm.encode()
    arm.robotName, arm.labels = "abc", [["a", "bé"], ["", "d"]]
    second = arm.encode()
    assert len(first) == len(second)
    for data in (first, second, first):
        assert kept.transcode(data) == generated.transcode(data)
    assert list(kept.layouts) == [len(first)] and kept.layouts[len(first)] is not None
    flags = first.index(b"\1\0", first.index(b"\0\1\2") + 3)  # flags [True, False], after fixedBlob
    true_as_two = first[:flags] + b"\2" + first[flags + 1 :]
    assert kept.transcode(true_as_two) == kept.transcode(first) == generated.transcode(true_as_two)
    name = first.index(b"a\0")
    with pytest.raises(DecodeError, match="invalid UTF-8"):
        kept.transcode(first[:name] + b"\xff" + first[name + 1 :])


# --- the swap scratch ------------------------------------------------------------------------------


BIG_PAIR = "package big; struct pair_t { int32_t n; double a[n]; int16_t k; float b[n]; double c[n]; }"


def test_long_arrays_of_one_message_do_not_share_scratch(tmp_path: Path) -> None:
    """Long arrays are swapped into a reused scratch: two of one message take two parts of it,
    and the next message's swaps do not touch what an earlier call returned. Both ways."""
    (tmp_path / "pair.lcm").write_text(BIG_PAIR)
    known = TypeLibrary.load([str(tmp_path / "pair.lcm")], drake=False).get("big.pair_t")
    rng = np.random.default_rng(3)

    def message(n: int) -> tuple[bytes, bytes]:
        a, b, c = rng.normal(size=n), rng.normal(size=n).astype(np.float32), rng.normal(size=n)
        lcm = (
            known.packed_fingerprint
            + struct.pack(">i", n)
            + a.astype(">f8").tobytes()
            + struct.pack(">h", -2)
        )
        lcm += b.astype(">f4").tobytes() + c.astype(">f8").tobytes()
        cdr = b"\0\1\0\0" + struct.pack("<iI", n, n) + a.astype("<f8").tobytes() + struct.pack("<h2xI", -2, n)
        cdr += b.astype("<f4").tobytes() + struct.pack("<I", n)
        cdr += bytes(-(len(cdr) - 4) & 7) + c.astype("<f8").tobytes()
        return lcm, cdr

    first_lcm, first_cdr = message(5000)
    got = known.to_cdr(first_lcm)
    assert got == first_cdr and known.from_cdr(got) == first_lcm
    for n in (5000, 20000, 300):
        lcm, cdr = message(n)
        assert known.to_cdr(lcm) == cdr and known.from_cdr(cdr) == lcm
    assert got == first_cdr


def test_threads_swap_in_scratch_of_their_own(tmp_path: Path) -> None:
    """Each thread has its own scratch: converting in parallel gives each message's own bytes."""
    (tmp_path / "pair.lcm").write_text(BIG_PAIR)
    known = TypeLibrary.load([str(tmp_path / "pair.lcm")], drake=False).get("big.pair_t")

    def lcm(n: int, value: float) -> bytes:
        doubles, floats = np.full(n, value, ">f8").tobytes(), np.full(n, value, ">f4").tobytes()
        return known.packed_fingerprint + struct.pack(">i", n) + doubles + b"\0\1" + floats + doubles

    messages = [lcm(3000 + 100 * index, float(index)) for index in range(8)]
    want = [known.to_cdr(data) for data in messages]
    with ThreadPoolExecutor(4) as pool:
        for _ in range(20):
            assert list(pool.map(known.to_cdr, messages)) == want
