"""Parsing `.lcm` files and computing fingerprints."""

from __future__ import annotations

import importlib
import struct

import pytest

from viewer_bridge.errors import SchemaError
from viewer_bridge.lcmcodec.codecs import CODECS, STRUCTS
from viewer_bridge.lcmcodec.schema import Dimension, fingerprint, parse_lcm

# Values printed by lcm-gen 1.5.3 (docs/PROTOCOLS.md section 1 and 2).
KNOWN_FINGERPRINTS = {
    "drake.lcmt_viewer_load_robot": 0x8987209B10AA2D39,
    "drake.lcmt_viewer_link_data": 0x51252725AF982A63,
    "drake.lcmt_viewer_geometry_data": 0x5D2E34CB3257DB07,
    "drake.lcmt_viewer_draw": 0x414F0BFE5B2F4244,
    "robotlocomotion.viewer2_comms_t": 0xD368E03F33C568BE,
    # Drake's point cloud types (checked against pydrake's classes below too).
    "drake.lcmt_point_cloud": 0x17F2C128B5D25A95,
    "drake.lcmt_point_cloud_field": 0xD2628D58FB331B3F,
    # Contact results (docs/PROTOCOLS.md section 9): printed by pydrake 1.51's classes.
    "drake.lcmt_contact_results_for_viz": 0x114C15EA77683B45,
    "drake.lcmt_point_pair_contact_info_for_viz": 0x124E4A5C0C2EE1E9,
    "drake.lcmt_hydroelastic_contact_surface_for_viz": 0xFD46C8E07468606E,
    "drake.lcmt_hydroelastic_quadrature_per_point_data_for_viz": 0x81278726783D83B3,
    "drake.lcmt_point": 0xAE7E5FBA5EECA11E,
    # Camera images (docs/PROTOCOLS.md section 12): printed by pydrake 1.51's classes.
    "drake.lcmt_image_array": 0x1572A7D08D9022E6,
    "drake.lcmt_image": 0xBD7080D565EC47D1,
    "drake.lcmt_header": 0x124E586663318E54,
    # Drake's drivers' and planners' types (docs/PROTOCOLS.md section 13): printed by pydrake's classes.
    "drake.lcmt_iiwa_command": 0xDDC7C7738C815334,
    "drake.lcmt_iiwa_status": 0xF16FB804284ABCA3,
    "drake.lcmt_schunk_wsg_command": 0x4553BC1BFF499216,
    "drake.lcmt_schunk_wsg_status": 0xEC6AEE3FC5AE4612,
    "drake.lcmt_robot_state": 0x84CFB1722D58BD59,
    "drake.lcmt_robot_plan": 0x0CD6AA5C6FC8B056,
}
# The types Drake's own Python package (pip drake) has classes for: their fingerprints must agree.
PYDRAKE_TYPES = sorted(name for name in KNOWN_FINGERPRINTS if name.startswith("drake."))


def test_every_type_is_defined() -> None:
    assert set(STRUCTS) == set(KNOWN_FINGERPRINTS)


@pytest.mark.parametrize("name", sorted(KNOWN_FINGERPRINTS))
def test_fingerprint_equals_lcm_gen(name: str, lcmgen: dict[str, type]) -> None:
    generated = lcmgen[name]._get_packed_fingerprint()  # type: ignore[attr-defined]
    assert CODECS[name].packed_fingerprint == generated
    assert CODECS[name].fingerprint == struct.unpack(">Q", generated)[0] == KNOWN_FINGERPRINTS[name]


@pytest.mark.parametrize("name", PYDRAKE_TYPES)
def test_fingerprint_equals_pydrake(name: str) -> None:
    pydrake_class = getattr(importlib.import_module("drake"), name.removeprefix("drake."))
    assert CODECS[name].packed_fingerprint == pydrake_class._get_packed_fingerprint()


def test_constants_come_from_the_schema() -> None:
    codec = CODECS["drake.lcmt_viewer_geometry_data"]
    assert [(c.name, c.value) for c in codec.definition.constants] == [
        ("BOX", 1),
        ("SPHERE", 2),
        ("CYLINDER", 3),
        ("MESH", 4),
        ("CAPSULE", 5),
        ("ELLIPSOID", 6),
    ]
    assert codec.message_class.ELLIPSOID == 6


def test_parses_multiple_declarators_and_comments() -> None:
    (parsed,) = parse_lcm("package p; /* c */ struct s { int32_t n, m; // x\n double v[n][3], w; }")
    assert parsed.full_name == "p.s"
    assert [(m.name, m.type_name, [d.size for d in m.dims]) for m in parsed.members] == [
        ("n", "int32_t", []),
        ("m", "int32_t", []),
        ("v", "double", ["n", "3"]),
        ("w", "double", []),
    ]
    assert fingerprint(parsed, {"p.s": parsed}) != 0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("struct s { int32_t a[n]; }", "array size 'n' is neither a constant nor an earlier member"),
        ("struct s { double n; int32_t a[n]; }", "must be an integer scalar member"),
        ("struct s { int32_t a }", "expected ','"),
        ("struct s { int32_t a[0]; }", "array size must be from 1 to 2147483647"),
        ("struct s { const string x = 1; }", "numeric type"),
        ("struct s { int32_t a; $ }", "unexpected character"),
        ("enum e { A }", "expected 'package' or 'struct'"),
        ("struct s { int32_t a;", "unexpected end of file"),
        ("struct s { const byte B = 1; }", "numeric type"),
        ("struct s { const int8_t B = 200; }", "200 does not fit in int8_t"),
        (
            "struct s { const int32_t N = 0; double x[N]; }",
            "must be an integer constant from 1 to 2147483647",
        ),
        (
            "struct s { const double N = 2.0; double x[N]; }",
            "must be an integer constant from 1 to 2147483647",
        ),
        ("struct s { int32_t a; double a; }", "'a' is declared twice"),
        ("struct s { const int32_t a = 1; double a; }", "'a' is declared twice"),
        ("struct s { int32_t class; }", "a member name 'class' is a Python keyword"),
        ("struct s { int32_t x[1.5]; }", "array size '1.5' is not a number"),
        ("package 9p; struct s { }", "'9' is not a package name"),
    ],
)
def test_schema_errors_name_file_and_line(text: str, message: str) -> None:
    with pytest.raises(SchemaError, match=message) as caught:
        parse_lcm(text, "bad.lcm")
    assert caught.value.path == "bad.lcm" and caught.value.line == 1


def test_arrays_sized_by_constants_hash_the_constants_literal_as_lcm_gen_does() -> None:
    """lcm-gen writes a dimension named by a constant as that constant's literal: `0x2`, not `2`."""
    (hexed,) = parse_lcm("struct hexdim_t { const int32_t HEX = 0x2; double a[HEX]; }")
    assert (
        hexed.members[0].dims == (Dimension("0x2", is_variable=False),)
        and hexed.members[0].dims[0].count == 2
    )
    assert (
        fingerprint(hexed, {"hexdim_t": hexed})
        == 0x5C67C30CCCA84513 << 1 & (1 << 64) - 1 | 0x5C67C30CCCA84513 >> 63
    )
    (decimal,) = parse_lcm("struct s { const int16_t N = 3; int32_t m; float q[N][m]; }")
    assert [(d.size, d.is_variable) for d in decimal.members[1].dims] == [("3", False), ("m", True)]


def test_comments_are_kept_for_structs_members_and_constants() -> None:
    (parsed,) = parse_lcm(
        "// the struct\n/* more\n * lines */\nstruct s {  // and its brace's\n  // a constant\n  const int8_t A = 1;\n"
        "  // two members\n  int32_t n, m;  // trailing: the last one's\n  /** doc\n   * comment */ double d; /* a */ // b\n"
        "  // c\n}\n",
        "c.lcm",
    )
    assert parsed.comment == "the struct\nmore\nlines\nand its brace's" and parsed.line == 4
    assert parsed.constants[0].comment == "a constant" and parsed.constants[0].text == "1"
    assert [m.comment for m in parsed.members] == ["two members", "", "doc\ncomment"]
    assert [m.trailing for m in parsed.members] == ["", "trailing: the last one's", "a\nb"]
    assert parsed.where == "c.lcm:4"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        # Constants that Python, C and a ROS 2 .msg file cannot all write as a literal.
        ("struct s {\n  const double X = nan;\n}", "nan is not a finite double"),
        ("struct s {\n  const double X = 1e999;\n}", "1e999 is not a finite double"),
        ("struct s {\n  const double X = -1e999;\n}", "-1e999 is not a finite double"),
        ("struct s {\n  const float X = 1e39;\n}", "1e39 is out of float's"),
        # Names the generated class has already, or that Python mangles in a class body.
        ("struct s {\n  int32_t __slots__;\n}", "a member name '__slots__' starts with two underscores"),
        ("struct s {\n  int32_t __eq__;\n}", "a member name '__eq__' starts with two underscores"),
        ("struct s {\n  int32_t __private;\n}", "a member name '__private' starts with two underscores"),
        ("struct s {\n  double _type_name;\n}", "'_type_name' is the name of an attribute every generated"),
        ("struct s {\n  string encode;\n}", "a member name 'encode' is the name of an attribute"),
        (
            "struct s {\n  int8_t field_names[2];\n}",
            "a member name 'field_names' is the name of an attribute",
        ),
        (
            "struct s {\n  const int32_t to_dict = 1;\n}",
            "a constant name 'to_dict' is the name of an attribute",
        ),
        (
            "struct s {\n  const double _codec = 1.0;\n}",
            "a constant name '_codec' is the name of an attribute",
        ),
        (
            "struct s {\n  const int32_t __init__ = 1;\n}",
            "a constant name '__init__' starts with two underscores",
        ),
        ("package p;\nstruct __x { int32_t a; }", "a struct name '__x' starts with two underscores"),
    ],
)
def test_what_generated_python_cannot_hold_is_refused_where_it_is_written(text: str, message: str) -> None:
    """Before, these parsed and failed later, in the generated code, with a plain Python error
    (`NameError: nan`, a slot that hid `encode`, a class whose `__slots__` was a constant)."""
    with pytest.raises(SchemaError) as caught:
        parse_lcm(text, "bad.lcm")
    assert message in caught.value.reason, caught.value
    assert str(caught.value).startswith("bad.lcm:2: ")


def test_names_with_one_underscore_and_builtins_names_are_fine() -> None:
    (parsed,) = parse_lcm("struct _U32 { const double _X = 1e38; int32_t _a, list, range; float f; }")
    assert [member.name for member in parsed.members] == ["_a", "list", "range", "f"]
    assert parsed.constants[0].value == 1e38
