"""JSON -> LCM (`LcmType.from_json`), held to lcm-gen's encoder: the values of random messages as
JSON (ROS 2 names, flat arrays), missing fields and length fields, and every refusal by field path."""

from __future__ import annotations

import base64
import contextlib
import json
import tracemalloc
from collections.abc import Mapping
from typing import Any

import drake
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from tests.lcmcodec.corpus import (
    CORPUS,
    TRANSLATOR_CORPUS,
    assert_refused,
    expected,
    generate_lcmgen,
    lcmgen_messages,
)
from viewer_bridge.errors import DecodeError, JsonValueError
from viewer_bridge.lcmcodec import json_to_lcm
from viewer_bridge.lcmcodec.json_to_lcm import MESSAGE_LIMIT
from viewer_bridge.lcmcodec.library import LcmType, TypeLibrary
from viewer_bridge.lcmcodec.schema import StructDef


def _structs(library: TypeLibrary) -> dict[str, StructDef]:
    return {known.full_name: known.definition for known in library.types()}


def _as_json(values: Any) -> Any:
    """Through JSON text and back, as a transport would hand them over (no infinities: not JSON)."""
    try:
        return json.loads(json.dumps(values, allow_nan=False))
    except ValueError:
        assume(False)


def _round_trips(
    known: LcmType, structs: Mapping[str, StructDef], classes: Mapping[str, type], examples: int
) -> None:
    @settings(max_examples=examples, deadline=None, suppress_health_check=list(HealthCheck))
    @given(lcmgen_messages(known.definition, structs, classes), st.booleans())
    def check(message: Any, drop_lengths: bool) -> None:
        data = message.encode()
        values = _as_json(expected(type(message).decode(data), known.definition, structs))
        assert known.from_json(values) == data
        if drop_lengths:  # every length field that sizes a one-dimensional array, derived from it
            # (one that sizes only multi-dimensional arrays cannot be told from an empty one: cols
            # of a 0 × cols matrix; test_lengths_are_derived_through_several_dimensions has those)
            for member in known.definition.members:
                if len(member.dims) == 1 and member.dims[0].is_variable:
                    values.pop(_ros(member.dims[0].size), None)
            assert known.from_json(values) == data

    check()


def _ros(name: str) -> str:
    from viewer_bridge.lcmcodec.rosnames import field_name

    return field_name(name)


def test_every_corpus_type_from_json(library: TypeLibrary, classes: dict[str, type]) -> None:
    types = [k for k in library.types() if k.source.startswith(str(CORPUS)) and k.ros_type]
    assert len(types) == 5
    for known in types:
        _round_trips(known, _structs(library), classes, 50)


def test_the_translators_corpus_from_json(tmp_path_factory: pytest.TempPathFactory) -> None:
    library = TypeLibrary.load([str(TRANSLATOR_CORPUS)], drake=False)
    classes = generate_lcmgen(tmp_path_factory.mktemp("translators_lcmgen"), TRANSLATOR_CORPUS)
    types = [k for k in library.types() if k.source.startswith(str(TRANSLATOR_CORPUS)) and k.ros_type]
    assert len(types) == 2
    for known in types:
        _round_trips(known, _structs(library), classes, 40)


def test_every_drake_type_from_json() -> None:
    library = TypeLibrary.load()
    types = [k for k in library.types() if k.source == "module drake" and k.ros_type]
    classes = {known.full_name: getattr(drake, known.definition.name) for known in types}
    for known in types:
        _round_trips(known, _structs(library), classes, 8)


@pytest.fixture(scope="module")
def iiwa() -> LcmType:
    return TypeLibrary.load().get("drake.lcmt_iiwa_command")


def _command(joints: list[float], torques: list[float], utime: int = 5) -> bytes:
    message = drake.lcmt_iiwa_command()
    message.utime, message.num_joints, message.joint_position = utime, len(joints), joints
    message.num_torques, message.joint_torque = len(torques), torques
    data: bytes = message.encode()
    return data


def test_what_a_ros_user_writes_for_an_iiwa_command(iiwa: LcmType) -> None:
    joints = [0.0, 0.5, -0.5, 1.0, 0, 2, -1.25]  # integers in a float array are numbers too
    assert iiwa.from_json({"utime": 5, "joint_position": joints}) == _command(joints, [])
    assert iiwa.from_json(
        {"utime": 5, "num_joints": 7, "joint_position": joints, "num_torques": 0}
    ) == _command(joints, [])
    assert iiwa.from_json({}) == _command([], [], utime=0)


def _refused(known: LcmType, value: Any, field: str, reason: str) -> JsonValueError:
    refused = assert_refused(known.from_json, value, JsonValueError, known, field, reason)
    assert isinstance(refused, DecodeError)
    return refused


@pytest.mark.parametrize(
    ("value", "field", "reason"),
    [
        ([], "", "expected an object, got an array"),
        ("x", "", "expected an object, got a string"),
        (None, "", "expected an object, got null"),
        (7, "", "expected an object, got 7"),
        ({"utime": 1, "jointPosition": []}, "jointPosition", "unknown field"),
        ({"utime": "1"}, "utime", "expected an integer, got a string"),
        ({"utime": 1.0}, "utime", "expected an integer, got 1.0"),
        ({"utime": True}, "utime", "expected an integer, got true"),
        ({"utime": None}, "utime", "expected an integer, got null"),
        ({"utime": 2**63}, "utime", "out of range"),
        ({"utime": -(2**63) - 1}, "utime", "out of range"),
        ({"utime": 10**400}, "utime", "an integer of 1329 bits is out of range"),
        ({"utime": 10**5000}, "utime", "an integer of 16610 bits is out of range"),
        ({"num_joints": 2**31}, "num_joints", "out of range"),
        ({"num_joints": -1}, "num_joints", "cannot be negative"),
        ({"joint_position": [1.0, "2"]}, "joint_position[1]", "expected a number, got a string"),
        ({"joint_position": [1.0, True]}, "joint_position[1]", "expected a number, got true"),
        ({"joint_position": [1.0, None]}, "joint_position[1]", "expected a number, got null"),
        ({"joint_position": [1.0, [2.0]]}, "joint_position[1]", "expected a number, got an array"),
        ({"joint_position": [float("nan")]}, "joint_position[0]", "not a finite number"),
        ({"joint_position": [0.0, float("-inf")]}, "joint_position[1]", "not a finite number"),
        ({"joint_position": [10**400]}, "joint_position[0]", "too large for a float64"),
        ({"joint_position": {"0": 1.0}}, "joint_position", "expected an array, got an object"),
        ({"joint_position": 1.0}, "joint_position", "expected an array, got 1.0"),
        ({"num_joints": 3, "joint_position": [1.0]}, "joint_position", "has 1 elements, but num_joints = 3"),
        ({"num_joints": 3}, "joint_position", "missing, but num_joints = 3"),
        ({"num_torques": 1, "joint_position": [1.0]}, "joint_torque", "missing, but num_torques = 1"),
    ],
)
def test_bad_values_name_their_field(iiwa: LcmType, value: Any, field: str, reason: str) -> None:
    _refused(iiwa, value, field, reason)


def test_what_the_corpus_refuses(library: TypeLibrary) -> None:
    arm = library.get("lab.robot.arm_state_t")
    _refused(arm, {"num_joints": 128}, "num_joints", "out of range -128..127")
    _refused(arm, {"joint_angles": [0.0] * 128}, "num_joints", "128, derived from joint_angles, is more than")
    _refused(arm, {"joint_angles": [0.0] * 2, "flags": [True]}, "flags", "has 1 elements, but num_joints = 2")
    _refused(arm, {"joint_angles": [0, 0], "flags": [True, 1]}, "flags[1]", "expected true or false, got 1")
    _refused(arm, {"gains": [1.0, 2.0]}, "gains", "has 2 elements, but its size is 4")
    _refused(arm, {"gains": [1.0, 2.0, 3.0, 1e39]}, "gains[3]", "out of float32's range")
    _refused(arm, {"temperature": -1e39}, "temperature", "out of float32's range")
    _refused(arm, {"mode": 128}, "mode", "out of range -128..127")
    _refused(arm, {"blob": [1, 256], "cols": 2}, "blob[1]", "out of range 0..255")
    _refused(arm, {"blob": [1, -1], "cols": 2}, "blob[1]", "out of range 0..255")
    _refused(arm, {"blob": "not base64!"}, "blob", "base64")
    _refused(arm, {"robot_name": 5}, "robot_name", "expected a string, got 5")
    _refused(arm, {"robot_name": "\ud800"}, "robot_name", "not encodable as UTF-8")
    _refused(arm, {"tip": []}, "tip", "expected an object, got an array")
    _refused(arm, {"tip": {"x": "1"}}, "tip.x", "expected a number, got a string")
    _refused(arm, {"tip": {"w": 1}}, "tip.w", "unknown field")
    two = {"joint_angles": [0, 0], "flags": [True, False]}
    _refused(
        arm, {**two, "waypoints": [{}, {"frame_id": 1}]}, "waypoints[1].frame_id", "expected a string, got 1"
    )
    _refused(arm, {**two, "waypoints": [{}, 3]}, "waypoints[1]", "expected an object, got 3")
    _refused(arm, {"corners": [{}] * 3}, "corners", "has 3 elements, but 2 × 2 = 2 × 2 = 4")
    _refused(
        arm, {"rows": 2, "cols": 3, "grid": [1] * 5}, "grid", "has 5 elements, but rows × cols = 2 × 3 = 6"
    )
    _refused(arm, {"grid": [1] * 6}, "grid", "has 6 elements, but rows × cols = 0 × 0 = 0")
    _refused(arm, {"tiny": [1, 2, 3]}, "tiny", "has 3 elements, but 2 × 2 = 2 × 2 = 4")
    _refused(arm, {"labels": ["a", "b"], "rows": 2}, "table", "missing, but 4 × rows = 4 × 2 = 8")
    plain = library.get("plain_status_t")
    _refused(plain, {"where": {"frame_id": None}}, "where.frame_id", "expected a string, got null")
    _refused(plain, {"ok": 1}, "ok", "expected true or false, got 1")


def test_lengths_are_derived_through_several_dimensions(
    library: TypeLibrary, classes: dict[str, type]
) -> None:
    """rows from table (maxJoints × rows), then cols from grid (rows × cols), blob from cols."""
    arm = classes["lab.robot.arm_state_t"]()
    arm.rows, arm.cols = 2, 3
    arm.gains = [0.0] * 4
    arm.grid = [[1, 2, 3], [4, 5, 6]]
    arm.table = [[1, 2]] * 4
    arm.cube = [[[0, 0, 0]] * 2] * 2
    arm.labels = [["", ""], ["", ""]]
    arm.blob = b"\x00\xff\x10"
    arm.raw2d = [b"ab", b"cd"]
    arm.fixedBlob, arm.tiny = b"\0\0\0", [[0, 0], [0, 0]]  # lcm-gen's defaults are not the right sizes
    arm.tip = classes["lab.geometry.point3d_t"]()
    arm.corners = [[classes["lab.geometry.point3d_t"]()] * 2] * 2
    values = {
        "table": [1, 2] * 4, "grid": [1, 2, 3, 4, 5, 6], "cube": [0] * 12, "labels": [""] * 4,
        "blob": base64.b64encode(b"\x00\xff\x10").decode(), "raw2d": list(b"abcd"),
    }  # fmt: skip
    assert library.get("lab.robot.arm_state_t").from_json(values) == arm.encode()


def test_huge_arrays_are_refused_before_their_elements(library: TypeLibrary) -> None:
    plain = library.get("plain_status_t")
    huge = [0.0] * (MESSAGE_LIMIT // 4 + 1)
    _refused(plain, {"samples": huge, "codes": [0] * len(huge)}, "samples", "more than 67108864 bytes")
    arm = library.get("lab.robot.arm_state_t")
    _refused(arm, {"joint_angles": [0.0] * 10**6}, "num_joints", "is more than its type int8_t holds (127)")


def test_deep_nesting_is_a_wrong_type_not_a_recursion(iiwa: LcmType) -> None:
    deep: Any = 1.0
    for _ in range(100_000):
        deep = [deep]
    _refused(iiwa, {"joint_position": deep}, "joint_position[0]", "expected a number, got an array")
    nested: Any = {}
    for _ in range(100_000):
        nested = {"utime": nested}
    _refused(iiwa, nested, "utime", "expected an integer, got an object")


def test_a_refused_type_has_no_way_back(library: TypeLibrary) -> None:
    with pytest.raises(JsonValueError, match="contains itself"):
        library.get("lab.robot.tree_node_t").from_json({})


_LIBRARY = TypeLibrary.load([str(CORPUS)], drake=False)
_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=4),
    max_leaves=20,
)
_FIELDS = st.sampled_from(["utime", "robot_name", "num_joints", "rows", "cols", "joint_angles", "grid", "blob",
                           "tip", "waypoints", "x", "frame_id", "samples", "num_samples", "where", "ok"])  # fmt: skip


@given(st.dictionaries(_FIELDS, _JSON, max_size=6) | _JSON)
@settings(max_examples=300, deadline=None)
def test_random_json_raises_only_json_value_errors(value: Any) -> None:
    for known in _LIBRARY.types():
        if known.ros_type:
            with contextlib.suppress(JsonValueError):
                data = known.from_json(value)
                assert known.from_cdr(known.to_cdr(data)) == data


# Each `inner` is 800,000 bytes of LCM however it is written: `{}` is its zeros.
NESTED_ZEROS = """package vbtest_big;
struct inner { double big[100000]; }
struct outer { int32_t n; inner items[n]; }
struct wrap { int32_t n; outer outers[n]; }
"""


@pytest.fixture(scope="module")
def big(tmp_path_factory: pytest.TempPathFactory) -> TypeLibrary:
    folder = tmp_path_factory.mktemp("big")
    (folder / "big.lcm").write_text(NESTED_ZEROS)
    return TypeLibrary.load([str(folder)], drake=False)


def test_a_short_json_claiming_a_huge_array_of_nested_messages_is_refused_before_building_it(
    big: TypeLibrary,
) -> None:
    """411 bytes of JSON said 100 nested messages: 80 MB of LCM were built before the size limit
    was seen, as a nested message counted as 1 byte. Its real fewest bytes are counted first now."""
    known = big.get("vbtest_big.outer")
    text = json.dumps({"items": [{}] * 100})
    assert len(text) < 500
    tracemalloc.start()
    try:
        error = assert_refused(known.from_json, json.loads(text), JsonValueError, known, "items",
                               "100 elements of at least 800000 bytes each make the message at least")  # fmt: skip
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert f"more than {MESSAGE_LIMIT} bytes" in error.reason
    assert peak < 4 << 20, f"{peak} bytes allocated on the way to the refusal"
    assert len(known.from_json({"items": [{}] * 2})) == 8 + 4 + 2 * 800_000  # what fits is built


def test_arrays_that_fit_alone_but_not_together_are_refused_at_the_one_that_passes_the_limit(
    big: TypeLibrary, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(json_to_lcm, "MESSAGE_LIMIT", 2_500_000)  # three inners, not four
    known = big.get("vbtest_big.wrap")
    assert (
        len(known.from_json({"outers": [{"items": [{}]}, {"items": [{}, {}]}]}))
        == 8 + 4 + 2 * 4 + 3 * 800_000
    )
    assert_refused(known.from_json, {"outers": [{"items": [{}, {}]}] * 2}, JsonValueError, known, "outers[1].items",
                   "2 elements of at least 800000 bytes each make the message at least 3200020 bytes")  # fmt: skip
