"""Generated codecs: byte-identical to lcm-gen, and strict on bad input."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.lcmcodec.corpus import generate_lcmgen
from tests.strategies import message_pairs, use_lcmgen
from viewer_bridge.errors import DecodeError, EncodeError
from viewer_bridge.lcmcodec.codecs import CODECS, DRAW, GEOMETRY_DATA, LOAD_ROBOT, VIEWER2_COMMS
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.lcmcodec.schema import MESSAGE_CLASS_ATTRIBUTES
from viewer_bridge.lcmcodec.serde import LcmMessage

NAMES = sorted(CODECS)


@pytest.fixture(autouse=True)
def _twins(lcmgen: dict[str, type]) -> None:
    use_lcmgen(lcmgen)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=150, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_encode_is_byte_identical_to_lcm_gen(name: str, data: st.DataObject) -> None:
    ours, theirs = data.draw(message_pairs(CODECS[name].definition))
    expected = theirs.encode()
    assert ours.encode() == expected
    decoded = CODECS[name].decode(expected)
    assert decoded == ours
    assert decoded.encode() == expected


def draw_message(names: list[str]) -> LcmMessage:
    count = len(names)
    return DRAW.message_class(
        timestamp=12,
        num_links=count,
        link_name=names,
        robot_num=list(range(count)),
        position=[[1.0, 2.0, 3.0]] * count,
        quaternion=[[1.0, 0.0, 0.0, 0.0]] * count,
    )


GOOD_DRAW = draw_message(["plant::a", "plant::b"]).encode()


def test_default_constructed_messages_encode() -> None:
    for codec in CODECS.values():
        message = codec.message_class()
        assert codec.decode(message.encode()) == message


@pytest.mark.parametrize(
    ("data", "field", "offset", "reason"),
    [
        (b"", "<fingerprint>", 0, "truncated"),
        (b"\0" * 8 + GOOD_DRAW[8:], "<fingerprint>", 0, "fingerprint 0000000000000000 is not"),
        (GOOD_DRAW[:15], "timestamp", 8, "truncated: needs 8 bytes, 7 remain"),
        (GOOD_DRAW[:18], "num_links", 16, "truncated"),
        (GOOD_DRAW[:16] + struct.pack(">i", -1) + GOOD_DRAW[20:], "link_name", 20, "negative count -1"),
        (GOOD_DRAW[:16] + struct.pack(">i", 2**31 - 1) + GOOD_DRAW[20:], "link_name", 20, "count 2147483647"),
        (GOOD_DRAW[:20] + struct.pack(">I", 0) + GOOD_DRAW[24:], "link_name[0]", 20, "string length 0"),
        (GOOD_DRAW[:20] + struct.pack(">I", 2**32 - 1) + GOOD_DRAW[24:], "link_name[0]", 24, "truncated"),
        (GOOD_DRAW[:24] + b"\xff" + GOOD_DRAW[25:], "link_name[0]", 24, "invalid UTF-8"),
        (GOOD_DRAW[:32] + b"X" + GOOD_DRAW[33:], "link_name[0]", 32, "not NUL-terminated"),
        (GOOD_DRAW + b"\0", "<end>", len(GOOD_DRAW), "1 trailing bytes"),
        (
            GOOD_DRAW[:-4] + struct.pack(">f", float("nan")),
            "quaternion[1][3]",
            len(GOOD_DRAW) - 4,
            "non-finite",
        ),
        (
            GOOD_DRAW[:-4] + struct.pack(">f", float("inf")),
            "quaternion[1][3]",
            len(GOOD_DRAW) - 4,
            "non-finite",
        ),
        (GOOD_DRAW[:-1], "quaternion", len(GOOD_DRAW) - 32, "count 8 needs at least 32 bytes, 31 remain"),
    ],
)
def test_bad_draw_names_type_field_and_offset(data: bytes, field: str, offset: int, reason: str) -> None:
    with pytest.raises(DecodeError) as caught:
        DRAW.strict.decode(data)
    error = caught.value
    assert (error.type_name, error.field, error.offset) == ("drake.lcmt_viewer_draw", field, offset)
    assert reason in error.reason
    assert str(error).startswith(f"drake.lcmt_viewer_draw.{field} at byte {offset}: ")


def test_nested_errors_carry_the_whole_field_path() -> None:
    geometry = GEOMETRY_DATA.message_class(type=2, num_float_data=1, float_data=[float("nan")])
    link = CODECS["drake.lcmt_viewer_link_data"].message_class(name="a", num_geom=1, geom=[geometry])
    data = LOAD_ROBOT.message_class(num_links=1, link=[link]).encode()
    with pytest.raises(DecodeError) as caught:
        LOAD_ROBOT.strict.decode(data)
    assert caught.value.field == "link[0].geom[0].float_data[0]"
    assert caught.value.type_name == "drake.lcmt_viewer_load_robot"
    assert data[caught.value.offset : caught.value.offset + 4] == struct.pack(">f", float("nan"))


def test_a_huge_count_is_refused_before_anything_is_allocated() -> None:
    claim = LOAD_ROBOT.packed_fingerprint + struct.pack(">i", 2**31 - 1)
    with pytest.raises(DecodeError, match="count 2147483647 needs at least") as caught:
        LOAD_ROBOT.decode(claim)
    assert caught.value.field == "link"


def test_byte_arrays_decode_to_bytes() -> None:
    message = VIEWER2_COMMS.message_class(
        utime=5, format="treeviewer_json", format_version_major=1, num_bytes=2, data=b"{}"
    )
    decoded = VIEWER2_COMMS.decode(message.encode())
    assert decoded.data == b"{}" and isinstance(decoded.data, bytes)


@pytest.mark.parametrize(
    ("message", "field", "reason"),
    [
        (draw_message(["a"]), None, None),
        (DRAW.message_class(num_links=2, link_name=["a"]), "link_name", "has 1 elements, expected 2"),
        (DRAW.message_class(timestamp=2**63), "timestamp, num_links", "too large"),
        (
            DRAW.message_class(
                num_links=1,
                link_name=["a"],
                robot_num=[0],
                position=[[1e39, 0, 0]],
                quaternion=[[1, 0, 0, 0]],
            ),
            "position",
            "float",
        ),
        (
            DRAW.message_class(
                num_links=1, link_name=[3], robot_num=[0], position=[[0, 0, 0]], quaternion=[[1, 0, 0, 0]]
            ),
            "link_name",
            "encode",
        ),
        (
            LOAD_ROBOT.message_class(num_links=1, link=["x"]),
            "link[0]",
            "expected drake.lcmt_viewer_link_data",
        ),
    ],
)
def test_encode_errors_name_the_field(message: LcmMessage, field: str | None, reason: str | None) -> None:
    if field is None:
        assert DRAW.decode(message.encode()) == message
        return
    with pytest.raises(EncodeError) as caught:
        message.encode()
    assert caught.value.field == field
    assert reason is not None and reason in caught.value.reason


@pytest.mark.parametrize("links", [12, 16, 100, 2000])  # both sides of the numpy threshold
def test_long_arrays_match_lcm_gen(links: int, lcmgen: dict[str, type]) -> None:
    rng = np.random.default_rng(links)
    theirs = lcmgen["drake.lcmt_viewer_draw"]()
    theirs.timestamp, theirs.num_links = -5, links
    theirs.link_name = [f"plant::m::l{i}" for i in range(links)]
    theirs.robot_num = rng.integers(-(2**31), 2**31, links).tolist()
    theirs.position = rng.normal(size=(links, 3)).astype(np.float32).tolist()
    theirs.quaternion = rng.normal(size=(links, 4)).astype(np.float32).tolist()
    data = theirs.encode()
    ours = DRAW.decode(data)
    assert (ours.position, ours.quaternion, ours.robot_num) == (
        theirs.position,
        theirs.quaternion,
        theirs.robot_num,
    )
    assert ours.encode() == data
    nan_at = len(data) - 16 * links + 4 * 9  # quaternion[2][1]
    broken = data[:nan_at] + struct.pack(">f", float("nan")) + data[nan_at + 4 :]
    with pytest.raises(DecodeError) as caught:
        DRAW.strict.decode(broken)
    assert (caught.value.field, caught.value.offset) == ("quaternion[2][1]", nan_at)


def test_finite_values_whose_sum_overflows_are_accepted() -> None:
    """Found by hypothesis: the finiteness screen once raised OverflowError for such a message."""
    codec = CODECS["drake.lcmt_hydroelastic_quadrature_per_point_data_for_viz"]
    message = codec.message_class()
    message.traction_Aq_W = [0.0, 3.3978799665285463e306, 1.7637143351970303e308]
    assert codec.decode(codec.encode(message)).traction_Aq_W == message.traction_Aq_W


def test_an_empty_array_with_absurd_outer_dimensions_is_refused_at_once() -> None:
    """bench/fuzz.py's lcm_generic (after 296,287 runs): `x[n][m][0]` decoded to n * m empty lists,
    for no bytes at all; rows beyond the bytes left (or 65,536) are a DecodeError now."""
    import struct as struct_module

    from viewer_bridge.errors import DecodeError
    from viewer_bridge.lcmcodec.schema import parse_lcm
    from viewer_bridge.lcmcodec.serde import compile_codecs

    (definition,) = parse_lcm("struct rows_t { int32_t n; int32_t m; int8_t z; double x[n][m][z]; }")
    codec = compile_codecs({"rows_t": definition})["rows_t"]
    with pytest.raises(DecodeError, match=r"rows_t.x at byte 17: shape \(2147483647, 2147483647, 0\)"):
        codec.decode(codec.packed_fingerprint + struct_module.pack(">iib", 2**31 - 1, 2**31 - 1, 0))
    assert codec.decode(codec.packed_fingerprint + struct_module.pack(">iib", 3, 2, 0)).x == [[[], []]] * 3


# Types named as builtins the generated code calls (`list(flat)`, `bytes(...)`) and as one of its
# helpers (`_U32`), nested in another type, whose member names are builtins its defaults call.
NAMESAKES = """package vbtest_names;
struct list { int32_t a; double xy[2]; }
struct bytes { string s; byte raw[3]; }
struct _U32 { double d; }
struct outer {
  int32_t range;
  int32_t n;
  list items[n];
  bytes blobs[2];
  _U32 u;
  byte data[3];
  double xyz[2];
  string name;
}
"""


def test_types_named_as_builtins_or_helpers_round_trip_as_lcm_gen_writes_them(tmp_path: Path) -> None:
    (tmp_path / "lcm").mkdir()
    (tmp_path / "lcm" / "names.lcm").write_text(NAMESAKES)
    classes = generate_lcmgen(tmp_path / "py", tmp_path / "lcm")  # lcm-gen takes these names too
    theirs = classes["vbtest_names.outer"]()
    theirs.range, theirs.n, theirs.data, theirs.xyz, theirs.name = 9, 2, b"\x01\x02\x03", [1.5, -2.5], "ok"
    theirs.items = [classes["vbtest_names.list"]() for _ in range(2)]
    theirs.items[1].a, theirs.items[1].xy = 7, [0.25, 4.0]
    # lcm-gen: raw = b""
    theirs.blobs[0].s, theirs.blobs[0].raw, theirs.blobs[1].raw = "blob", bytes(3), b"xyz"
    theirs.u.d = 3.75
    data = theirs.encode()

    library = TypeLibrary.load([str(tmp_path / "lcm")], drake=False)
    known = library.get("vbtest_names.outer")
    codec = library.codecs(known.full_name)[known.full_name]
    ours = codec.decode(data)
    assert ours.items[1].to_dict() == {"a": 7, "xy": [0.25, 4.0]} and ours.blobs[1].raw == b"xyz"
    assert ours.data == b"\x01\x02\x03" and ours.xyz == [1.5, -2.5] and ours.u.d == 3.75
    assert [type(item).__name__ for item in ours.items] == ["list", "list"]
    assert codec.encode(ours) == data
    assert known.from_cdr(known.to_cdr(data)) == data
    assert classes["vbtest_names.outer"].decode(known.from_cdr(known.to_cdr(data))).encode() == data
    # Built by keyword, a member named `range` does not hide the builtin that fills `xyz`.
    built = codec.message_class(range=9, n=2, items=ours.items, blobs=ours.blobs, u=ours.u, data=b"\x01\x02\x03",
                                xyz=[1.5, -2.5], name="ok")  # fmt: skip
    assert built == ours and codec.message_class(range=1).xyz == [0.0, 0.0]
    with pytest.raises(TypeError, match="vbtest_names.outer has no member 'rnage'"):
        codec.message_class(rnage=1)


def test_every_attribute_a_generated_class_has_is_a_name_the_schema_refuses() -> None:
    """The schema refuses member and constant names in MESSAGE_CLASS_ATTRIBUTES: it must hold every
    name a generated class has that is not its own field or constant (dunders are refused apart)."""
    for codec in CODECS.values():
        cls = codec.message_class
        own = {member.name for member in codec.definition.members} | {
            c.name for c in codec.definition.constants
        }
        defined = {name for klass in cls.__mro__[:-1] for name in vars(klass)} - own
        assert {name for name in defined if not name.startswith("__")} <= MESSAGE_CLASS_ATTRIBUTES, cls
        assert {"_codec", "encode"} <= defined
