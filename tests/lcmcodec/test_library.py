"""TypeLibrary: where types come from, conflicts and errors, lookups, and to_dict."""

from __future__ import annotations

import shutil
import struct
import sys
import zlib
from pathlib import Path

import drake
import pytest

from tests.lcmcodec.corpus import CORPUS, PLAIN_TAIL, generate_lcmgen
from viewer_bridge.errors import DecodeError, SchemaError
from viewer_bridge.lcmcodec.codecs import STRUCTS
from viewer_bridge.lcmcodec.library import LcmType, TypeLibrary
from viewer_bridge.lcmcodec.rosnames import ros_topic_for_channel


@pytest.fixture(scope="module")
def library() -> TypeLibrary:
    return TypeLibrary.load([str(CORPUS)], drake=False)


def test_the_project_types_are_always_known_and_drakes_by_default() -> None:
    without = TypeLibrary.load(drake=False)
    assert {known.full_name for known in without.types()} == set(STRUCTS)
    with_drake = TypeLibrary.load()
    names = {known.full_name for known in with_drake.types()}
    drake_types = {f"drake.{name}" for name in dir(drake) if name.startswith("lcmt_")}
    assert len(drake_types) > 40 and drake_types <= names
    status = with_drake.get("drake.lcmt_panda_status")  # one the project does not ship
    assert status.source == "module drake" and status.ros_type == "drake_lcm_msgs/msg/LcmtPandaStatus"
    assert status.packed_fingerprint == drake.lcmt_panda_status._get_packed_fingerprint()
    # Our own copy of a Drake type wins the source, and agrees with Drake's class.
    for name in ("lcmt_viewer_draw", "lcmt_iiwa_status", "lcmt_iiwa_command", "lcmt_robot_plan"):
        ours = with_drake.get(f"drake.{name}")
        assert f"lcmtypes/{name}.lcm:" in ours.source
        assert ours.packed_fingerprint == getattr(drake, name)._get_packed_fingerprint()


def test_a_folder_is_searched_recursively_and_a_file_alone_works(library: TypeLibrary) -> None:
    corpus = {known.full_name for known in library.types()} - set(STRUCTS)
    assert corpus == {
        "lab.geometry.point3d_t",
        "lab.robot.arm_state_t",
        "lab.robot.collision_t",
        "lab.robot.forest_t",
        "lab.robot.heartbeat_t",
        "lab.robot.pulse_t",
        "lab.robot.tree_node_t",
        "plain_status_t",
    }
    single = TypeLibrary.load([str(CORPUS / "lab/geometry/point3d_t.lcm")], drake=False)
    point = single.get("lab.geometry.point3d_t")
    assert point.source == f"{CORPUS}/lab/geometry/point3d_t.lcm:5"


def test_lcm_gen_python_modules_by_import_name_give_the_same_types(
    tmp_path: Path, library: TypeLibrary
) -> None:
    generate_lcmgen(tmp_path)
    sys.path.insert(0, str(tmp_path))
    try:
        from_modules = TypeLibrary.load(["lab.robot", "plain_status_t"], drake=False)
    finally:
        sys.path.remove(str(tmp_path))
    for known in library.types():
        if known.full_name.startswith(("lab.", "plain")):
            twin = from_modules.get(known.full_name)  # nested ones imported by their names
            assert twin.packed_fingerprint == known.packed_fingerprint, known.full_name
            assert twin.source.startswith("module ")
            assert twin.ros_type == known.ros_type and twin.refused == known.refused
            if known.ros_type:
                assert _fields(twin.msg_definition) == _fields(known.msg_definition)


def _fields(definition: str) -> list[str]:
    """The field and constant lines (a class does not know a constant's declared type or comments)."""
    return [line.split("#")[0].strip() for line in definition.splitlines() if line and not line.startswith("#")
            and "=" not in line]  # fmt: skip


def test_one_name_defined_differently_twice_names_both_places(tmp_path: Path) -> None:
    other = tmp_path / "other"
    other.mkdir()
    (other / "point.lcm").write_text("package lab.geometry;\nstruct point3d_t { double x; }\n")
    with pytest.raises(SchemaError) as caught:
        TypeLibrary.load([str(CORPUS), str(other)], drake=False)
    message = str(caught.value)
    assert message.startswith(f"{other}/point.lcm:2: type lab.geometry.point3d_t differs")
    assert f"{CORPUS}/lab/geometry/point3d_t.lcm:5" in message


def test_two_definitions_that_differ_only_in_a_nested_types_name_are_refused(tmp_path: Path) -> None:
    """`inner_a` and `inner_b` have one shape, so `holder` hashes alike with either: before, the
    second definition was merged into the first and its data decoded as the other type."""
    first, second = tmp_path / "first", tmp_path / "second.lcm"
    first.mkdir()
    shapes = "struct inner_a { double v; }\nstruct inner_b { double v; }\n"
    (first / "types.lcm").write_text(f"package vbtest_twin;\n{shapes}struct holder {{ inner_a x; }}\n")
    second.write_text("package vbtest_twin;\n\nstruct holder\n{\n  inner_b x;\n}\n")
    with pytest.raises(SchemaError) as caught:
        TypeLibrary.load([str(first), str(second)], drake=False)
    assert str(caught.value) == (
        f"{second}:3: type vbtest_twin.holder differs from its definition at {first}/types.lcm:4: "
        "member vbtest_twin.inner_b x here, vbtest_twin.inner_a x there"
    )


def test_the_same_definition_twice_is_fine(tmp_path: Path) -> None:
    shutil.copy(CORPUS / "lab/geometry/point3d_t.lcm", tmp_path / "copy.lcm")
    both = TypeLibrary.load([str(CORPUS), str(tmp_path)], drake=False)
    assert both.get("lab.geometry.point3d_t").ros_type == "lab_geometry_lcm_msgs/msg/Point3dT"


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("package a;\nstruct s {\n  int32_t n;\n  double x[m];\n}\n", "bad.lcm:4: array size 'm' is neither"),
        ("struct s { int32_t n; }\nstruct t { s inner; u other; }\n", "bad.lcm:2: t.other: unknown type 'u'"),
    ],
)
def test_a_bad_lcm_file_is_one_line_with_its_file_and_line(tmp_path: Path, text: str, reason: str) -> None:
    (tmp_path / "bad.lcm").write_text(text)
    with pytest.raises(SchemaError) as caught:
        TypeLibrary.load([str(tmp_path)], drake=False)
    assert str(caught.value).startswith(f"{tmp_path}/{reason}") and "\n" not in str(caught.value)


def test_a_source_that_is_neither_file_nor_module() -> None:
    with pytest.raises(SchemaError, match="no_such_module_xyz: cannot import"):
        TypeLibrary.load(["no_such_module_xyz"], drake=False)
    with pytest.raises(SchemaError, match="no such .lcm file"):
        TypeLibrary.load(["./missing/types.lcm"], drake=False)
    with pytest.raises(SchemaError, match="module json: holds no lcm-gen'd Python class"):
        TypeLibrary.load(["json"], drake=False)


def test_recursive_and_colliding_types_are_refused_with_one_warning_each(library: TypeLibrary) -> None:
    tree = library.get("lab.robot.tree_node_t")
    assert tree.ros_type is None and tree.refused and "lab.robot.tree_node_t contains itself" in tree.refused
    assert "lab.robot.tree_node_t" in library.get("lab.robot.forest_t").refused  # type: ignore[operator]
    assert "'jointAngle' and 'joint_angle'" in library.get("lab.robot.collision_t").refused  # type: ignore[operator]
    warned = [line for line in library.warnings if "lab.robot.tree_node_t (" in line]
    assert len(warned) == 1 and "tree_node_t.lcm:4" in warned[0]
    assert len(library.warnings) == 3
    assert tree.ros2msg == tree.rihs01 == tree.msg_definition == ""


def test_lookups(library: TypeLibrary) -> None:
    arm = library.get("lab.robot.arm_state_t")
    assert isinstance(arm, LcmType)
    assert library.for_data(arm.packed_fingerprint + b"anything") is arm
    assert library.for_data(b"\0" * 8) is None and library.for_data(b"") is None
    names = [known.full_name for known in library.types()]
    assert names == sorted(names)
    definitions = library.ros_definitions()
    assert "lab_robot_lcm_msgs/msg/ArmStateT" in definitions and "lcm_msgs/msg/PlainStatusT" in definitions
    assert not any("TreeNodeT" in name for name in definitions)
    assert definitions["lab_robot_lcm_msgs/msg/ArmStateT"] == arm.msg_definition
    with pytest.raises(KeyError):
        library.get("lab.robot.nothing_t")


def test_to_dict_summarises_bytes_unless_asked(library: TypeLibrary) -> None:
    status = library.get("plain_status_t")
    body = struct.pack(">qd?", 5, float("nan"), True) + struct.pack(">dddI", 1, 2, 3, 3) + b"ab\0"
    data = status.packed_fingerprint + body + struct.pack(">i2f2b", 2, 0.5, -1.0, 3, -4) + PLAIN_TAIL
    record = status.to_dict(data)
    # NaN kept
    assert record["timestamp"] == 5 and record["ok"] is True and record["value"] != record["value"]
    # ROS 2 names, as from_dict takes
    assert record["where"] == {"x": 1.0, "y": 2.0, "z": 3.0, "frame_id": "ab"}
    assert record["fixed_shorts"] == [1, -2, 3]
    assert record["samples"] == [0.5, -1.0] and record["codes"] == [3, -4] and record["tags"] == ["a", ""]
    comms = TypeLibrary.load(drake=False).get("robotlocomotion.viewer2_comms_t")
    payload = b'{"a": 1}'
    message = (
        TypeLibrary.load(drake=False)
        .codecs(comms.full_name)[comms.full_name]
        .message_class(
            utime=1,
            format="f",
            format_version_major=1,
            format_version_minor=0,
            num_bytes=len(payload),
            data=payload,
        )
    )
    encoded = message.encode()
    assert comms.to_dict(encoded)["data"] == {"bytes": 8, "crc32": f"{zlib.crc32(payload):08x}"}
    assert comms.to_dict(encoded, bytes_summary=False)["data"] == {"utf8": '{"a": 1}'}
    assert comms.from_dict(comms.to_dict(encoded, bytes_summary=False)) == encoded  # exact inverses
    with pytest.raises(DecodeError, match="viewer2_comms_t"):
        comms.to_dict(encoded[:-1])
    # the older names are aliases of the same two
    assert comms.to_json(encoded) == comms.to_dict(encoded)
    assert comms.from_json(comms.to_json(encoded, bytes_summary=False)) == encoded


@pytest.mark.parametrize(
    ("channel", "topic"),
    [
        ("IIWA_STATUS", "/lcm/IIWA_STATUS"),
        ("left-arm.status", "/lcm/left_arm_status"),
        ("a b/c", "/lcm/a_b_c"),
    ],
)
def test_channels_become_topics(channel: str, topic: str) -> None:
    assert ros_topic_for_channel(channel) == topic


def test_the_folder_of_an_lcm_gen_package_is_imported_from_its_parent(
    tmp_path: Path, library: TypeLibrary
) -> None:
    generate_lcmgen(tmp_path)
    sys.path_importer_cache.clear()
    for name in [name for name in sys.modules if name == "lab" or name.startswith("lab.")]:
        del sys.modules[name]  # imported from another folder by an earlier test
    from_folder = TypeLibrary.load([str(tmp_path / "lab")], drake=False)  # subpackages robot, geometry
    arm = from_folder.get("lab.robot.arm_state_t")
    assert arm.source == f"module lab in {tmp_path}"
    assert arm.packed_fingerprint == library.get("lab.robot.arm_state_t").packed_fingerprint
    assert str(tmp_path) not in sys.path
    (tmp_path / "empty").mkdir()
    with pytest.raises(SchemaError, match="is a folder with no .lcm files, no __init__.py, and no lcm-gen'd"):
        TypeLibrary.load([str(tmp_path / "empty")], drake=False)


def test_the_folder_lcm_gen_wrote_into_is_understood_by_its_bare_name(
    tmp_path: Path, library: TypeLibrary, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`lcm-gen -p --ppath gen ...` then `--lcm-types gen`: its packages and loose modules, not a
    module named gen."""
    generate_lcmgen(tmp_path / "gen")
    sys.path_importer_cache.clear()
    for name in [name for name in sys.modules if name.split(".")[0] in ("lab", "plain_status_t")]:
        del sys.modules[name]  # imported from another folder by an earlier test
    monkeypatch.chdir(tmp_path)
    from_folder = TypeLibrary.load(["gen"], drake=False)
    for name in ("lab.robot.arm_state_t", "plain_status_t"):
        assert from_folder.get(name).packed_fingerprint == library.get(name).packed_fingerprint
    assert from_folder.get("plain_status_t").source == f"module plain_status_t in {tmp_path / 'gen'}"


def test_types_of_one_shape_share_a_fingerprint_and_the_channel_picks_among_them() -> None:
    # Drake's iiwa and allegro commands have the same fields, so the same fingerprint.
    library = TypeLibrary.load()
    data = drake.lcmt_iiwa_command().encode()
    iiwa, allegro = library.get("drake.lcmt_iiwa_command"), library.get("drake.lcmt_allegro_command")
    assert iiwa.packed_fingerprint == allegro.packed_fingerprint == data[:8]
    assert library.sharing_fingerprint(iiwa) == [allegro, iiwa]
    assert library.for_data(data, "IIWA_COMMAND") is iiwa
    assert library.for_data(data, "left-arm.iiwa_command") is iiwa
    assert library.for_data(data, "ALLEGRO_COMMAND") is allegro
    assert library.for_data(data, "COMMAND") is allegro  # no name in the channel: the first by name
    assert library.for_data(data) is allegro
