"""Hostile type definitions (issue 51 rows 6-8): `.lcm` files and ROS 2 `.msg` text shaped to cost
time or Python's stack. Type processing is linear in the definitions' size; a type nested deeper
than `MAX_NESTING` levels, an array of more than `MAX_DIMENSIONS` dimensions and an array size
lcm-gen refuses are refused with a `SchemaError` naming file:line (LCM) or the type (ROS 2)."""

from __future__ import annotations

import random
import subprocess
import sys
import textwrap
from collections.abc import Mapping
from pathlib import Path

import pytest

from viewer_bridge.cli.main import main
from viewer_bridge.errors import SchemaError
from viewer_bridge.lcmcodec.from_ros import map_ros_types
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.lcmcodec.schema import (
    MAX_DIMENSIONS,
    MAX_NESTING,
    StructDef,
    check_references,
    fingerprints,
    parse_lcm,
)

TOP = Path(__file__).resolve().parents[2]


def chain(levels: int) -> str:
    """An `.lcm` file of `levels` types, each holding the next in a sized array; the last an int."""
    lines = ["package c;"]
    lines += [f"struct t{i} {{ int32_t n; t{i + 1} next[n]; }}" for i in range(levels - 1)]
    return "\n".join([*lines, f"struct t{levels - 1} {{ int32_t x; }}", ""])


def diamond(levels: int) -> str:
    """`levels` types, each holding two of the next: 2^levels paths from the first to the last."""
    lines = ["package d;"] + [f"struct t{i} {{ t{i + 1} a; t{i + 1} b; }}" for i in range(levels - 1)]
    return "\n".join([*lines, f"struct t{levels - 1} {{ int32_t x; }}", ""])


def finishes(code: str, seconds: float = 120.0) -> str:
    """What `code` prints, run in a Python of its own that must end within a generous `seconds`
    (the quadratic and exponential versions took minutes to hours; a hang fails, it is not waited out)."""
    result = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                            cwd=TOP, timeout=seconds)  # fmt: skip
    assert result.returncode == 0, result.stderr
    return result.stdout


def _reference_fingerprint(
    struct: StructDef, structs: Mapping[str, StructDef], parents: tuple[str, ...]
) -> int:
    """LCM's rule as its specification says it, recursion and all (exponential in a diamond)."""
    if struct.full_name in parents:
        return 0
    value = struct.base_hash()
    for member in struct.members:
        if not member.is_primitive:
            value += _reference_fingerprint(structs[member.type_name], structs, (*parents, struct.full_name))
    value &= (1 << 64) - 1
    return ((value << 1) & ((1 << 64) - 1)) + (value >> 63)


def test_memoised_fingerprints_are_lcms_own_on_random_types_with_cycles() -> None:
    """The memo is sound: a type's hash depends on its parents only within its recursive group."""
    rng = random.Random(51)
    for _ in range(200):
        count = rng.randint(1, 7)
        lines = []
        for i in range(count):
            members = [f"int32_t n{j}; t{rng.randrange(count)} m{j}[n{j}];" for j in range(rng.randint(0, 3))]
            lines.append(f"struct t{i} {{ int8_t k; {' '.join(members)} }}")
        structs = {s.full_name: s for s in parse_lcm("\n".join(lines))}
        check_references(structs)
        expected = {name: _reference_fingerprint(s, structs, ()) for name, s in structs.items()}
        assert fingerprints(structs) == expected, "\n".join(lines)


def test_a_diamond_of_lcm_types_loads_at_once() -> None:
    """Row 6: a diamond 22 types deep took 209 s (the hash recursed without a memo); here 60 deep."""
    out = finishes(f"""
        import tempfile, pathlib
        from viewer_bridge.lcmcodec.library import TypeLibrary
        folder = pathlib.Path(tempfile.mkdtemp())
        (folder / "d.lcm").write_text({diamond(60)!r})
        library = TypeLibrary.load([str(folder)], drake=False)
        top = library.get("d.t0")
        print(top.packed_fingerprint.hex(), len(library.codecs("d.t0")), len(top.ros2msg) > 0)
    """)
    fingerprint, codecs, described = out.split()
    assert len(fingerprint) == 16 and codecs == "60" and described == "True"


def test_a_struct_of_100k_members_parses_in_linear_time() -> None:
    """Row 6: each member was checked against every earlier one (100k: over 120 s)."""
    out = finishes("""
        from viewer_bridge.lcmcodec.schema import parse_lcm, fingerprints
        members = "".join(f"  int32_t n{i}; double a{i}[n{i}];\\n" for i in range(50_000))
        [big] = parse_lcm("struct big {\\n" + members + "}\\n")
        print(len(big.members), fingerprints({"big": big})["big"] > 0)
    """)
    assert out.split() == ["100000", "True"]


def test_many_types_sharing_a_wide_one_map_to_ros_in_linear_time() -> None:
    """Row 6: each type was searched for a cycle through all it nests (20,000 types each holding
    one that holds 20,000: minutes); now only within its recursive group."""
    out = finishes("""
        from viewer_bridge.lcmcodec.schema import parse_lcm, check_references
        from viewer_bridge.lcmcodec.rosmsg import map_to_ros
        n = 20_000
        text = "".join(f"struct a{i} {{ hub h; }}\\n" for i in range(n))
        text += "struct hub {" + "".join(f" b{i} m{i};" for i in range(n)) + " }\\n"
        text += "".join(f"struct b{i} {{ int8_t x; }}\\n" for i in range(n))
        structs = {s.full_name: s for s in parse_lcm(text)}
        check_references(structs)
        print(len(map_to_ros(structs).messages))
    """)
    assert out.split() == ["40001"]


def test_a_type_at_the_nesting_limit_works_and_one_deeper_is_refused_naming_its_line(tmp_path: Path) -> None:
    """Row 7: a 5,000-type chain raised RecursionError; `MAX_NESTING` levels work end to end."""
    (tmp_path / "ok.lcm").write_text(chain(MAX_NESTING))
    library = TypeLibrary.load([str(tmp_path / "ok.lcm")], drake=False)
    top = library.get("c.t0")
    message = top.from_json({"next": [{"next": [{}]}]})
    assert top.from_cdr(top.to_cdr(message)) == message
    assert top.to_json(message)["next"][0]["next"][0]["n"] == 0
    for levels in (MAX_NESTING + 1, 5_000):
        (tmp_path / "deep.lcm").write_text(chain(levels))
        with pytest.raises(SchemaError) as raised:
            TypeLibrary.load([str(tmp_path / "deep.lcm")], drake=False)
        assert str(raised.value) == (
            f"{tmp_path / 'deep.lcm'}:2: c.t0 nests types {levels} levels deep, more than the {MAX_NESTING} a type may"
        )


def test_a_recursive_type_still_loads_and_counts_its_group_once(tmp_path: Path) -> None:
    (tmp_path / "tree.lcm").write_text(
        "package r;\nstruct node { int32_t n; node children[n]; leaf tip; }\nstruct leaf { int8_t x; }\n"
    )
    library = TypeLibrary.load([str(tmp_path)], drake=False)
    codec = library.codecs("r.node")["r.node"]
    message = codec.message_class(n=1, children=[codec.message_class(n=0, children=[], tip=None)], tip=None)
    assert codec.decode(codec.encode(message)).n == 1


def test_dimensions_past_the_limit_are_refused_naming_the_line_and_the_limit_works(tmp_path: Path) -> None:
    """Row 7: 5,000 `[1]` dimensions: `SyntaxError: too many nested parentheses` in generated code."""
    (tmp_path / "ok.lcm").write_text(
        "package x;\nstruct dims {\n  int32_t n;\n  int8_t y" + "[1]" * (MAX_DIMENSIONS - 1) + "[n];\n}\n"
    )
    top = TypeLibrary.load([str(tmp_path / "ok.lcm")], drake=False).get("x.dims")
    message = top.from_json({"y": [5, 6]})
    assert top.to_json(message) == {"n": 2, "y": [5, 6]}
    assert top.from_cdr(top.to_cdr(message)) == message
    for count in (MAX_DIMENSIONS + 1, 5_000):
        (tmp_path / "many.lcm").write_text("package x;\nstruct dims {\n  int8_t y" + "[1]" * count + ";\n}\n")
        with pytest.raises(
            SchemaError, match=f"many.lcm:3: 'y' has more than {MAX_DIMENSIONS} array dimensions"
        ):
            TypeLibrary.load([str(tmp_path / "many.lcm")], drake=False)


@pytest.mark.parametrize(
    ("declaration", "reason"),
    [
        (
            "double x[4000000000];",
            "array size must be from 1 to 2147483647 (int32's largest), not 4000000000",
        ),
        (
            "int8_t y[99999999999999999999999999];",
            "array size must be from 1 to 2147483647 (int32's largest), not 99999999999999999999999999",
        ),  # fmt: skip
        (
            "int8_t z[0x80000000];",
            "array size must be from 1 to 2147483647 (int32's largest), not 0x80000000",
        ),
        (
            "const int64_t BIG = 4000000000; int8_t w[BIG];",
            "array size 'BIG' must be an integer constant from 1",
        ),
        ("int8_t v[65536][65536];", "'v' has more than 2147483647 elements (int32's largest)"),
    ],
)
def test_array_sizes_lcm_gen_refuses_are_refused_at_load_naming_the_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], declaration: str, reason: str
) -> None:
    """Row 8: `double x[4000000000]` and `int8_t y[1e26]` were accepted, and `ros-interfaces
    generate` wrote `int8[1e26]`; lcm-gen refuses both (a constant size is above 0 and fits int32)."""
    (tmp_path / "big.lcm").write_text(f"package x;\nstruct big {{\n  {declaration}\n}}\n")
    with pytest.raises(SchemaError) as raised:
        TypeLibrary.load([str(tmp_path / "big.lcm")], drake=False)
    assert str(raised.value).startswith(f"{tmp_path / 'big.lcm'}:3: {reason}")
    out = tmp_path / "src"
    assert main(["ros-interfaces", "generate", "--lcm-types", str(tmp_path / "big.lcm"), "-o", str(out)]) == 2
    assert f"big.lcm:3: {reason}" in capsys.readouterr().err
    assert not any(path.suffix == ".msg" for path in out.rglob("*")) if out.exists() else True
    (tmp_path / "fits.lcm").write_text("package x;\nstruct fits {\n  int8_t y[2147483647];\n}\n")
    assert TypeLibrary.load([str(tmp_path / "fits.lcm")], drake=False).get("x.fits").refused is None


def ros_definitions(texts: dict[str, str]) -> dict[str, tuple[list[object], list[object]]]:
    from rosbags.typesys import get_types_from_msg

    found: dict[str, tuple[list[object], list[object]]] = {}
    for name, text in texts.items():
        found.update(get_types_from_msg(text, f"deep_msgs/msg/{name}"))
    return found


def test_a_deep_ros_chain_is_refused_naming_the_type_not_a_recursion_error() -> None:
    """Row 7: a 3,000-deep bag type raised RecursionError; the types within the limit still map."""
    texts = {f"T{i}": f"T{i + 1} a\n" for i in range(3_000)} | {"T3000": "int32 x\n"}
    mapping = map_ros_types(ros_definitions(texts), ["deep_msgs/msg/T0"])
    deepest = f"deep_msgs/msg/T{3_000 - MAX_NESTING}"
    assert (
        mapping.refused[deepest]
        == f"it nests types {MAX_NESTING + 1} levels deep, more than the {MAX_NESTING} a type may"
    )
    assert mapping.refused["deep_msgs/msg/T0"] == (
        f"field a: deep_msgs/msg/T1 is refused (it nests types {MAX_NESTING + 1} levels deep, more than the "
        f"{MAX_NESTING} a type may)"
    )
    assert f"deep_msgs/msg/T{3_001 - MAX_NESTING}" in mapping.structs and len(mapping.structs) == MAX_NESTING


def test_a_diamond_of_ros_types_in_a_bag_converts_at_once(tmp_path: Path) -> None:
    """Row 6: a 3.4 KB bag of a 24-deep diamond took over 240 s to `convert`; here 40 deep."""
    texts = {f"T{i}": f"T{i + 1} a\nT{i + 1} b\n" for i in range(40)} | {"T40": "int32 x\n"}
    schema = texts["T0"] + "".join(f"{'=' * 80}\nMSG: deep_msgs/{name}\n{text}" for name, text in texts.items()
                                   if name != "T0")  # fmt: skip
    bag = tmp_path / "diamond.mcap"
    from mcap.writer import Writer

    with bag.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros2")
        channel = writer.register_channel("/deep", "cdr", writer.register_schema("deep_msgs/msg/T0", "ros2msg",
                                                                                 schema.encode()))  # fmt: skip
        writer.add_message(channel, log_time=1000, data=b"\x00\x01\x00\x00" + bytes(8), publish_time=0)
        writer.finish()
    out = finishes(f"""
        from viewer_bridge.cli.bag_to_lcm import bag_to_lcm
        result = bag_to_lcm({str(bag)!r}, {str(tmp_path / "out.lcmlog")!r})
        print(result.channels, result.bad)
    """)
    assert "{'/deep': 'deep'} Counter({'/deep': 1})" in out  # 8 bytes are not 2^40 ints: counted, not hung
