"""The translation tables: their codes match the specs, mistakes are clear, the reference is current."""

from __future__ import annotations

from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_typestore

from viewer_bridge.cli.main import main
from viewer_bridge.errors import ConfigError
from viewer_bridge.formats.mappings import format_names, load_tables, reference_markdown, tables
from viewer_bridge.lcmcodec.codecs import GEOMETRY_DATA
from viewer_bridge.model.scene import (
    SHAPE_KINDS,
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    HalfSpace,
    MeshFile,
    Pose,
    Sphere,
)
from viewer_bridge.util.resources import data_dir
from viewer_bridge.util.yamldoc import YamlDocument


def test_drake_codes_are_the_schemas() -> None:
    table = tables("drake")["geometry_data"]
    assert dict(table.types) == {name: GEOMETRY_DATA.constant(name) for name in table.types}


def test_ros_codes_are_jazzys() -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    for name, typename in (
        ("shape", "shape_msgs/msg/SolidPrimitive"),
        ("marker", "visualization_msgs/msg/Marker"),
    ):
        constants = {constant: value for constant, _, value in store.fielddefs[typename][0]}
        table = tables("ros")[name]
        assert table.target == typename
        assert {type_name: constants[type_name] for type_name in table.types} == dict(table.types)


def test_every_table_covers_every_shape() -> None:
    assert format_names() == ["drake", "foxglove", "ign", "rerun", "ros", "tree_viewer"]
    for format_name in format_names():
        for table in tables(format_name).values():
            assert set(table.rules) == set(SHAPE_KINDS)


def test_expanding_without_poses_gives_the_same_rules_and_shapes() -> None:
    # A capsule lowered to three parts, an ellipsoid to a mesh, a half-space to a box, in every table.
    shapes = [Box((1.0, 2.0, 3.0)), Capsule(0.5, 2.0), Ellipsoid((1.0, 2.0, 3.0)), HalfSpace()]
    lowered = 0
    for format_name in format_names():
        for table in tables(format_name).values():
            for shape in shapes:
                if table.rule_for(shape).unsupported is not None:
                    continue
                posed = table.expand(shape, Pose((1.0, 0.0, 0.0)))
                assert table.expand_unposed(shape) == [(rule, part) for rule, part, _ in posed]
                lowered += len(posed) > 1 or posed[0][1] is not shape
    assert lowered >= 5


@pytest.mark.parametrize(
    ("shape", "table", "expected"),
    [
        (Cylinder(0.5, 2.0), ("ros", "shape"), {"dimensions": [2.0, 0.5]}),  # height first
        (Cylinder(0.5, 2.0), ("drake", "geometry_data"), {"float_data": [0.5, 2.0]}),  # radius first
        (Sphere(0.5), ("ros", "marker"), {"scale": [1.0, 1.0, 1.0]}),  # diameter
        (Ellipsoid((1.0, 2.0, 3.0)), ("ros", "marker"), {"scale": [2.0, 4.0, 6.0]}),
        (Capsule(0.5, 2.0), ("ign", "geometry"), {"capsule.radius": 0.5, "capsule.length": 2.0}),
        (
            Cylinder(0.5, 2.0),
            ("foxglove", "primitive"),
            {"size": [1.0, 1.0, 2.0], "bottom_scale": 1.0, "top_scale": 1.0},
        ),  # fmt: skip
        (Ellipsoid((1.0, 2.0, 3.0)), ("foxglove", "primitive"), {"size": [2.0, 4.0, 6.0]}),
        (Box((1.0, 2.0, 3.0)), ("tree_viewer", "geometry"), {"lengths": [1.0, 2.0, 3.0]}),
        (
            MeshFile("/a.obj", (1.0, 2.0, 3.0)),
            ("tree_viewer", "geometry"),
            {"filename": "/a.obj", "scale": [1.0, 2.0, 3.0]},
        ),
    ],
)
def test_rules_read_shapes_and_invert(
    shape: object, table: tuple[str, str], expected: dict[str, object]
) -> None:
    rule = tables(table[0])[table[1]].rule_for(shape)  # type: ignore[arg-type]
    assert rule.values(shape) == expected  # type: ignore[arg-type]
    if rule.invertible:
        assert rule.shape_from(expected) == shape


def table_file(tmp_path: Path, shapes: str, types: str = "{BOX: 1, SPHERE: 2}") -> YamlDocument:
    rules = {
        kind: "{type: BOX}" for kind in SHAPE_KINDS if kind not in ("box", "sphere")
    }  # every kind but the two under test
    lines = [f"      {kind}: {rule}" for kind, rule in rules.items()]
    text = (
        "format: test\ntables:\n  t:\n    target: T\n"
        f"    types: {types}\n    shapes:\n{shapes}" + "\n".join(lines) + "\n"
    )
    path = tmp_path / "test.yaml"
    path.write_text(text)
    return YamlDocument.read(path)


@pytest.mark.parametrize(
    ("shapes", "line", "reason"),
    [
        ("      box: {type: CUBE}\n      sphere: {type: SPHERE}\n", 7, "tables.t.shapes.box.type: unknown type 'CUBE'"),
        ("      box: {type: BOX, fields: {size: [size.x, size.q]}}\n      sphere: {type: SPHERE}\n", 7,
         "'size.q' is not a number"),
        ("      box: {type: BOX, fields: {size: [size]}}\n      sphere: {type: SPHERE}\n", 7, "box.size needs .x/.y/.z"),
        ("      box: {type: BOX, fields: {size: [width]}}\n      sphere: {type: SPHERE}\n", 7, "box has no field 'width'"),
        ("      box: {as: explode}\n      sphere: {type: SPHERE}\n", 7, "unknown lowering 'explode'"),
        ("      box: {type: BOX, as: half_space_box}\n      sphere: {type: SPHERE}\n", 7, "or 'as' (a lowering)"),
        ("      box: {type: BOX}\n", 6, "tables.t.shapes: no rule for sphere"),
        ("      box: {type: BOX}\n      teapot: {type: BOX}\n      sphere: {type: SPHERE}\n", 8, "unknown shape kind"),
        ("      box: {type: BOX, colour: red}\n      sphere: {type: SPHERE}\n", 7,
         "box.colour: unknown key 'colour'; known keys: type, as, fields, encoder, message, unsupported, note"),
        ("      box: {type: BOX\n", 8, "not valid YAML"),
    ],
)  # fmt: skip
def test_table_mistakes_name_file_line_and_key(tmp_path: Path, shapes: str, line: int, reason: str) -> None:
    with pytest.raises(ConfigError) as caught:
        load_tables(table_file(tmp_path, shapes))
    assert caught.value.line == line, str(caught.value)
    assert reason in str(caught.value) and str(caught.value).startswith(f"{tmp_path / 'test.yaml'}:{line}:")


def test_unknown_encoders_are_refused(tmp_path: Path) -> None:
    document = table_file(tmp_path, "      box: {type: BOX, encoder: magic}\n      sphere: {type: SPHERE}\n")
    with pytest.raises(ConfigError, match="unknown encoder 'magic' .known: mesh."):
        load_tables(document, ["mesh"])


def test_reference_is_generated_from_the_tables(capsys: pytest.CaptureFixture[str]) -> None:
    reference = (data_dir("mappings") / "REFERENCE.md").read_text()
    assert reference == reference_markdown(format_names()), (
        "run: viewer-bridge mappings > mappings/REFERENCE.md"
    )
    assert main(["mappings"]) == 0
    assert capsys.readouterr().out == reference
    assert "| cylinder | CYLINDER = 3 | `dimensions` = [length, radius] |" in reference
