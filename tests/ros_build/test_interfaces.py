"""Interface packages generated from `.msg` definitions (tests/ros_interfaces_corpus.py), built
into the venv by `ros_interfaces.build` and checked against real peers: rclpy nodes, rosbags' CDR
and its RIHS01 type hashes, and colcon building the generated sources in a workspace.

The corpus is built once into the venv and kept: later sessions find it current (by the hash of
its sources) and build nothing.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tests.lcmcodec.corpus import CORPUS, expected, generate_lcmgen
from tests.peers import RosProbe
from tests.ros_interfaces_corpus import BASE, DEFINITIONS, MAIN
from viewer_bridge.cli.main import main
from viewer_bridge.errors import RosInterfaceError
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.lcmcodec.schema import Member, StructDef
from viewer_bridge.ros_build import interfaces as ros_interfaces
from viewer_bridge.transports.ros2 import message_class

TYPES = sorted(DEFINITIONS)


@pytest.fixture(scope="module")
def corpus_built() -> None:
    ros_interfaces.build(DEFINITIONS, log=print)  # nothing to do when the venv has it already
    chosen = ros_interfaces.packages(DEFINITIONS)
    digests = ros_interfaces.digests(chosen)
    assert all(ros_interfaces.current(package, digests[package.name]) for package in chosen)


def _typestore() -> Any:
    store = get_typestore(Stores.EMPTY)
    for typename, text in DEFINITIONS.items():
        store.register(get_types_from_msg(text, typename))
    return store


def _values(typename: str) -> dict[str, Any]:
    """Field values of each corpus type (nested ones as dicts), none of them a default."""
    point = {"x": 1.5, "y": -2.25, "z": 1e300}
    blob = {"name": "blob \u00e9", "kind": 1, "size": 3, "data": [0, 7, 255], "valid": True}
    sample = {
        "utime": -(2**62),
        "num_joints": 7,
        "position_fixed": [0.5 * index - 1 for index in range(7)],
        "velocity": [3.25, -1e-300],
        "torque": [0.5, -8.0, 2.25],
        "joint_names": ["iiwa_joint_1", "", "iiwa_joint_7"],
        "flags": [-32768, 0, 32767],
        "ok": True,
        "tip": point,
        "path": [point, {"x": 0.0, "y": 4.0, "z": -4.0}],
        "ends": [{"x": 1.0, "y": 2.0, "z": 3.0}, point],
        "blob": blob,
    }
    return {
        f"{BASE}/msg/Point": point,
        f"{BASE}/msg/Blob": blob,
        f"{MAIN}/msg/JointSample": sample,
        f"{MAIN}/msg/Empty": {},
    }[typename]


def _nested_type(typename: str, field: str) -> str | None:
    """The message type of a field, or None for a primitive one."""
    package = typename.split("/")[0]
    for line in DEFINITIONS[typename].splitlines():
        words = line.split("#")[0].split()
        if len(words) >= 2 and words[1] == field and "/" in words[0]:
            other, name = words[0].split("[")[0].split("/")
            return f"{other}/msg/{name}"
        if len(words) >= 2 and words[1] == field and words[0][:1].isupper():
            return f"{package}/msg/{words[0].split('[')[0]}"
    return None


def _rclpy_message(typename: str, values: dict[str, Any]) -> Any:
    message = message_class(typename)()
    for field, value in values.items():
        nested = _nested_type(typename, field)
        if nested is None:
            setattr(message, field, value)
        elif isinstance(value, list):
            setattr(message, field, [_rclpy_message(nested, item) for item in value])
        else:
            setattr(message, field, _rclpy_message(nested, value))
    return message


def _rosbags_message(store: Any, typename: str, values: dict[str, Any]) -> Any:
    fields: dict[str, Any] = {}
    for field, value in values.items():
        nested = _nested_type(typename, field)
        if nested is not None:
            fields[field] = (
                [_rosbags_message(store, nested, item) for item in value]
                if isinstance(value, list)
                else _rosbags_message(store, nested, value)
            )
        elif isinstance(value, list) and not (value and isinstance(value[0], str)):
            dtype = {"data": np.uint8, "torque": np.float32, "flags": np.int16}.get(field, np.float64)
            fields[field] = np.array(value, dtype=dtype)
        else:
            fields[field] = value
    if typename.endswith("/Empty"):
        fields["structure_needs_at_least_one_member"] = 0  # rosbags spells out rosidl's placeholder
    return store.types[typename](**fields)


def _plain(message: Any) -> Any:
    """An rclpy message as plain values (nested messages as dicts, arrays as lists)."""
    if hasattr(message, "get_fields_and_field_types"):
        return {field: _plain(getattr(message, field)) for field in message.get_fields_and_field_types()}
    if isinstance(message, (list, tuple, np.ndarray)) or type(message).__name__ == "array":
        return [_plain(item) for item in message]
    if isinstance(message, (bytes, bytearray)):
        return list(message)
    return message.item() if isinstance(message, np.generic) else message


def test_each_package_is_complete_and_names_the_packages_it_nests(tmp_path: Path) -> None:
    folders = ros_interfaces.generate_packages(DEFINITIONS, tmp_path)
    assert [folder.name for folder in folders] == [BASE, MAIN]  # the nested package first
    base, main = folders
    xml = (main / "package.xml").read_text()
    assert '<package format="3">' in xml and f"<name>{MAIN}</name>" in xml
    for line in (
        "<buildtool_depend>rosidl_default_generators</buildtool_depend>",
        "<exec_depend>rosidl_default_runtime</exec_depend>",
        "<member_of_group>rosidl_interface_packages</member_of_group>",
        f"<depend>{BASE}</depend>",
    ):
        assert line in xml
    assert "<depend>" not in (base / "package.xml").read_text()
    cmake = (main / "CMakeLists.txt").read_text()
    assert f"find_package({BASE} REQUIRED)" in cmake
    files = '"msg/Empty.msg" "msg/JointSample.msg"'
    assert f"rosidl_generate_interfaces(${{PROJECT_NAME}} {files} DEPENDENCIES {BASE})" in cmake
    assert sorted(path.name for path in (base / "msg").iterdir()) == ["Blob.msg", "Point.msg"]
    assert (main / "msg" / "JointSample.msg").read_text() == DEFINITIONS[f"{MAIN}/msg/JointSample"]


def test_a_package_is_rebuilt_when_its_sources_or_a_nested_package_change() -> None:
    before = ros_interfaces.digests(ros_interfaces.packages(DEFINITIONS))
    changed = dict(DEFINITIONS)
    changed[f"{BASE}/msg/Point"] += "float64 w\n"
    after = ros_interfaces.digests(ros_interfaces.packages(changed))
    assert after[BASE] != before[BASE] and after[MAIN] != before[MAIN]  # MAIN nests Point
    changed = dict(DEFINITIONS)
    changed[f"{MAIN}/msg/Empty"] += "# a comment only\n"
    after = ros_interfaces.digests(ros_interfaces.packages(changed))
    assert after[BASE] == before[BASE] and after[MAIN] != before[MAIN]
    assert ros_interfaces.digests(ros_interfaces.packages(DEFINITIONS)) == before


@pytest.mark.parametrize(
    ("definitions", "message"),
    [
        ({"Bad_msgs/msg/X": "int32 a\n"}, "'Bad_msgs/msg/X' is not a ROS 2 message name"),
        ({"a_msgs/srv/X": "int32 a\n"}, "'a_msgs/srv/X' is not a ROS 2 message name"),
        # A name is matched whole: `$` alone took a final newline, and the .msg file's name with it.
        ({"a_msgs/msg/X\n": "int32 a\n"}, "'a_msgs/msg/X\\n' is not a ROS 2 message name"),
        ({"a_msgs\n/msg/X": "int32 a\n"}, "'a_msgs\\n/msg/X' is not a ROS 2 message name"),
        ({"a_msgs/msg/X": "float64[ x\n"}, "a_msgs/msg/X: not a valid .msg definition: Could not parse"),
        (
            {"a_msgs/msg/X": "b_msgs/Y y\n", "b_msgs/msg/Y": "a_msgs/X x\n"},
            "interface packages that use each other cannot be built: a_msgs -> b_msgs -> a_msgs",
        ),
    ],
)
def test_definitions_that_cannot_make_packages_are_refused_naming_the_type(
    definitions: dict[str, str], message: str
) -> None:
    with pytest.raises(RosInterfaceError) as raised:
        ros_interfaces.packages(definitions)
    assert str(raised.value).startswith(message) and "\n" not in str(raised.value)


def test_definitions_rosidl_refuses_fail_the_build_in_one_line_naming_the_package_and_log() -> None:
    bad = {"vbtest_bad_lcm_msgs/msg/Bad": "float64 jointAngles\n"}  # rosidl: field names are lower case
    with pytest.raises(RosInterfaceError) as raised:
        ros_interfaces.build(bad)
    text = str(raised.value)
    log = ros_interfaces.log_path(sys.prefix, "vbtest_bad_lcm_msgs")
    assert "\n" not in text
    assert text == f"configuring vbtest_bad_lcm_msgs failed (exit 1); its log: {log}"
    assert "jointAngles" in log.read_text()
    assert not (Path(sys.prefix) / "share" / "vbtest_bad_lcm_msgs").exists()


def test_a_prefix_that_cannot_be_written_is_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    with pytest.raises(RosInterfaceError) as raised:
        ros_interfaces.build(DEFINITIONS, prefix=blocker / "venv")
    assert str(raised.value) == (
        f"cannot build ROS 2 interface packages into {blocker / 'venv'}: "
        f"{blocker / 'venv' / 'share'} is not writable (Not a directory)"
    )


def test_a_build_into_the_venv_has_the_c_type_supports_rclpy_uses_and_no_cpp_ones(corpus_built: None) -> None:
    lib = Path(sys.prefix) / "lib"
    for part in ("generator_c", "typesupport_c", "typesupport_fastrtps_c", "typesupport_introspection_c"):
        assert (lib / f"lib{MAIN}__rosidl_{part}.so").is_file()
    for part in ("typesupport_cpp", "typesupport_fastrtps_cpp", "typesupport_introspection_cpp"):
        assert not (lib / f"lib{MAIN}__rosidl_{part}.so").exists()
    assert not (Path(sys.prefix) / "include" / MAIN / MAIN / "msg" / "joint_sample.hpp").exists()
    # a workspace's package keeps them all: C++ nodes may use it
    assert "AMENT_EXTENSIONS" not in ros_interfaces.cmake_lists(ros_interfaces.packages(DEFINITIONS)[1])


def test_a_current_build_builds_nothing(corpus_built: None, capsys: pytest.CaptureFixture[str]) -> None:
    assert ros_interfaces.build(DEFINITIONS, log=print) == []
    assert capsys.readouterr().out == ""


@pytest.mark.parametrize("typename", TYPES)
def test_rosbags_cdr_reads_back_in_rclpy_as_the_same_values(corpus_built: None, typename: str) -> None:
    store = _typestore()
    values = _values(typename)
    raw = bytes(store.serialize_cdr(_rosbags_message(store, typename, values), typename))
    message = deserialize_message(raw, message_class(typename))
    expected = _plain(_rclpy_message(typename, values))
    assert _plain(message) == expected
    if values:  # the nested values really are the ones set, not defaults
        assert expected != _plain(message_class(typename)())
    # And back: rclpy's bytes read by rosbags are the same values (compared as rosbags writes them:
    # Fast-CDR leaves its padding bytes unset, so rclpy's own bytes differ there).
    back = store.deserialize_cdr(bytes(serialize_message(message)), typename)
    assert bytes(store.serialize_cdr(back, typename)) == raw


@pytest.fixture
def probes() -> Any:
    first, second = RosProbe("corpus_publisher"), RosProbe("corpus_peer")
    yield first, second
    first.close()
    second.close()


def test_each_type_round_trips_between_rclpy_nodes_with_rosbags_type_hash(
    corpus_built: None, probes: tuple[RosProbe, RosProbe]
) -> None:
    source, peer = probes
    store = _typestore()
    for index, typename in enumerate(TYPES):
        topic = f"/vb_test/corpus_{index}"
        received = peer.subscribe(topic, typename)
        publisher = source.publisher(topic, typename)
        assert source.wait_for(lambda publisher=publisher: publisher.get_subscription_count() == 1), typename
        sent = _rclpy_message(typename, _values(typename))
        publisher.publish(sent)
        assert peer.wait_for(lambda received=received: len(received) == 1), f"{typename} never arrived"
        assert _plain(received[0]) == _plain(sent)
        info = peer.node.get_publishers_info_by_topic(topic)[0]
        # What rmw_zenoh peers match by: rosidl's hash of the built type is rosbags' of the text.
        assert str(info.topic_type_hash) == store.hash_rihs01(typename)


def test_the_cli_generate_needs_an_output_folder(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ros-interfaces", "generate"]) == 2
    assert "generate needs -o DIR" in capsys.readouterr().err


def test_the_cli_generates_drakes_types_by_default_and_the_packages_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["ros-interfaces", "generate", "-o", str(tmp_path / "all")]) == 0
    folders = capsys.readouterr().out.split()
    assert str(tmp_path / "all" / "drake_lcm_msgs") in folders
    command = (tmp_path / "all" / "drake_lcm_msgs" / "msg" / "LcmtPandaCommand.msg").read_text()
    assert command.startswith("# LCM type drake.lcmt_panda_command\n")  # pydrake's class: no comments
    iiwa = (tmp_path / "all" / "drake_lcm_msgs" / "msg" / "LcmtIiwaCommand.msg").read_text()
    assert "int32 num_torques\n" in iiwa and "# Joint torques" in iiwa  # lcmtypes/'s file: its comments
    draw = (tmp_path / "all" / "drake_lcm_msgs" / "msg" / "LcmtViewerDraw.msg").read_text()
    assert "int64 timestamp  # simulation time in milliseconds\n" in draw  # lcmtypes/'s file: its comments
    lab = [
        "ros-interfaces",
        "generate",
        "lab_robot_lcm_msgs",
        "--lcm-types",
        str(CORPUS),
        "-o",
        str(tmp_path / "lab"),
    ]
    assert main(lab) == 0
    capsys.readouterr()
    stale = tmp_path / "lab" / "lab_robot_lcm_msgs" / "msg" / "GoneT.msg"  # as if a type an earlier run wrote
    stale.write_text("int8 x\n")
    assert main(lab) == 0  # over its own output: rewritten
    said = capsys.readouterr()
    assert said.out.split() == [
        str(tmp_path / "lab" / name) for name in ("lab_geometry_lcm_msgs", "lab_robot_lcm_msgs")
    ]
    assert not stale.exists()
    # The types left out are named, with the reason.
    assert (
        "viewer-bridge ros-interfaces: lab.robot.tree_node_t (" in said.err and "contains itself" in said.err
    )
    assert main([*lab[:2], "lab_arm_lcm_msgs", *lab[3:]]) == 2
    error = capsys.readouterr().err
    assert (
        "no LCM type maps to the package lab_arm_lcm_msgs (known: " in error and "lab_robot_lcm_msgs" in error
    )


def test_generate_says_which_types_it_wrote_and_that_drakes_own_need_pydrake(tmp_path: Path) -> None:
    """Where pydrake is not installed, Drake's types the project does not ship (lcmt_panda_status)
    are left out, in one line naming the extra; each package written is named with its types."""
    code = "import sys; sys.modules['drake'] = None\nfrom viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", code, "ros-interfaces", "generate", "-o", str(tmp_path)],
                            capture_output=True, text=True, timeout=300)  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [
        str(tmp_path / "drake_lcm_msgs"),
        str(tmp_path / "robotlocomotion_lcm_msgs"),
    ]
    lines = result.stderr.splitlines()
    assert lines[0] == (
        "viewer-bridge ros-interfaces: Drake's other LCM types (lcmt_panda_status, lcmt_scope, lcmt_allegro_command "
        "and the rest) left out: they come with pydrake's drake module, not installed: pip install 'viewer-bridge[drake]'"
    )
    written = sorted(path.stem for path in (tmp_path / "drake_lcm_msgs" / "msg").glob("*.msg"))
    # shipped: step 7 of the tour
    assert {"LcmtViewerDraw", "LcmtIiwaCommand", "LcmtSchunkWsgCommand"} <= set(written)
    assert "LcmtPandaStatus" not in written
    assert (
        lines[1]
        == f"viewer-bridge ros-interfaces: wrote drake_lcm_msgs: {len(written)} types ({', '.join(written)})"
    )
    assert lines[2:] == [
        "viewer-bridge ros-interfaces: wrote robotlocomotion_lcm_msgs: 1 type (Viewer2CommsT)"
    ]
    # With pydrake (this venv), nothing is said of Drake's types: they are written.
    full = subprocess.run([sys.executable, "-m", "viewer_bridge", "ros-interfaces", "generate", "-o", str(tmp_path / "all")],
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert full.returncode == 0 and "left out" not in full.stderr, full.stderr
    assert (tmp_path / "all" / "drake_lcm_msgs" / "msg" / "LcmtIiwaCommand.msg").is_file()
    assert "wrote drake_lcm_msgs: " in full.stderr and "LcmtIiwaCommand" in full.stderr


# The corpus's lab.robot and lab.geometry packages, renamed: the venv may hold lab_*_lcm_msgs built,
# which must not be what the workspace's build is checked with.
RENAMED = {"lab.": "vbws."}
ROBOT, GEOMETRY = "vbws_robot_lcm_msgs", "vbws_geometry_lcm_msgs"
WORKSPACE_TYPES = ["vbws.robot.arm_state_t", "vbws.robot.pulse_t", "vbws.geometry.point3d_t"]


def _renamed_corpus(folder: Path) -> Path:
    """tests/lcmtypes_corpus/lab/ (comments and all) with its packages renamed, in `folder`."""
    for path in sorted((CORPUS / "lab").rglob("*.lcm")):
        text = path.read_text()
        for old, new in RENAMED.items():
            text = text.replace(old, new)
        target = folder / path.relative_to(CORPUS)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text)
    return folder


def _leaf(type_name: str, k: int) -> Any:
    """A value of an LCM primitive type that is nobody's default, different for each `k`."""
    if type_name in ("int8_t", "int16_t", "int32_t", "int64_t"):
        bits = int(type_name[3:-2])
        return (97 * k) % 2**bits - 2 ** (bits - 1)  # the sign bit set for the first ones: the width shows
    return {
        "byte": 255 - k % 256,
        "float": 0.5 + k,  # exact in float32
        "double": -1e300 / (k + 3),
        "boolean": k % 2 == 1,
        "string": f"\u00e9 {k}",
    }[type_name]


def _lcm_message(name: str, structs: dict[str, StructDef], classes: dict[str, type], seed: int = 1) -> Any:
    """An lcm-gen'd message of type `name` with a value of its own in every field (two elements
    along each variable dimension)."""
    struct = structs[name]
    message = classes[name]()
    counts = {dim.size for member in struct.members for dim in member.dims if dim.is_variable}

    def element(member: Member, k: int) -> Any:
        if member.is_primitive:
            return _leaf(member.type_name, k)
        return _lcm_message(member.type_name, structs, classes, 7 * k)

    def array(member: Member, shape: list[int], k: int) -> Any:
        if len(shape) == 1 and member.type_name == "byte":
            return bytes(_leaf("byte", k + index) for index in range(shape[0]))
        if len(shape) == 1:
            return [element(member, k + index) for index in range(shape[0])]
        return [array(member, shape[1:], k + 10 * index) for index in range(shape[0])]

    for index, member in enumerate(struct.members):
        k = seed + 100 * index
        if member.name in counts:
            value: Any = 2
        elif member.dims:
            value = array(member, [2 if dim.is_variable else dim.count for dim in member.dims], k)
        else:
            value = element(member, k)
        setattr(message, member.name, value)
    return message


def _package_depends(xml: str) -> list[tuple[str, str]]:
    """A package.xml's dependency elements (and its groups), as (tag, package)."""
    tags = ("depend", "build_depend", "build_export_depend", "buildtool_depend", "buildtool_export_depend",
            "exec_depend", "test_depend", "doc_depend", "member_of_group", "group_depend")  # fmt: skip
    root = ElementTree.fromstring(xml)
    return sorted((element.tag, element.text or "") for element in root if element.tag in tags)


@pytest.mark.slow
@pytest.mark.timeout(2700)  # colcon's build alone may take 1800 s
def test_colcon_builds_packages_generated_from_lcm_files_and_rclpy_reads_the_bridges_cdr(
    tmp_path: Path,
) -> None:
    """A user's colcon workspace with the packages of real .lcm files (comments carried over),
    built by colcon against the venv's ROS 2 wheels (the venv is the underlay's ament prefix);
    rclpy's classes from its install space read the CDR the bridge writes for lcm-gen's messages."""
    lcm_types = _renamed_corpus(tmp_path / "lcmtypes")
    workspace = tmp_path / "ws"
    generated = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "ros-interfaces", "generate", ROBOT,
         "--lcm-types", str(lcm_types), "-o", str(workspace / "src")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert generated.returncode == 0, generated.stderr
    # The package asked for and the one it nests, nothing else of the library (drake_lcm_msgs).
    assert generated.stdout.split() == [str(workspace / "src" / name) for name in (GEOMETRY, ROBOT)]
    src = workspace / "src"
    common = [("buildtool_depend", "ament_cmake"), ("buildtool_depend", "rosidl_default_generators"),
              ("exec_depend", "rosidl_default_runtime"), ("member_of_group", "rosidl_interface_packages")]  # fmt: skip
    assert _package_depends((src / GEOMETRY / "package.xml").read_text()) == sorted(common)
    assert _package_depends((src / ROBOT / "package.xml").read_text()) == sorted(
        [*common, ("depend", GEOMETRY)]
    )
    assert f"DEPENDENCIES {GEOMETRY})" in (src / ROBOT / "CMakeLists.txt").read_text()
    assert "DEPENDENCIES" not in (src / GEOMETRY / "CMakeLists.txt").read_text()
    point = (src / GEOMETRY / "msg" / "Point3dT.msg").read_text()
    assert point.startswith("# A point in a named frame.\n# Used by vbws.robot's types, across packages.\n")
    assert "string frame_id  # the frame's name\n" in point
    arm = (src / ROBOT / "msg" / "ArmStateT.msg").read_text()
    assert "# joint angles, radians\nfloat64[] joint_angles\n" in arm
    assert sorted(path.name for path in (src / ROBOT / "msg").iterdir()) == [
        # the recursive and colliding types have no ROS 2 form
        "ArmStateT.msg", "HeartbeatT.msg", "PulseT.msg"
    ]  # fmt: skip

    _write_cpp_node(src / "vbws_show")  # a C++ user of the generated package, as docs/lcm-types.md says

    prefix = sys.prefix
    env = dict(os.environ, AMENT_PREFIX_PATH=prefix, CMAKE_PREFIX_PATH=prefix)
    colcon = Path(sys.executable).parent / "colcon"
    start = time.monotonic()
    build = subprocess.run(
        [
            str(colcon),
            "build",
            "--event-handlers",
            "console_direct-",
            "--cmake-args",
            f"-DPython3_EXECUTABLE={sys.executable}",
            "-DBUILD_TESTING=OFF",
        ],  # fmt: skip
        cwd=workspace,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    print(f"colcon build of {GEOMETRY}, {ROBOT} and a C++ node: {time.monotonic() - start:.0f} s")
    shown = subprocess.run(
        ["bash", "-c", "source install/setup.bash && exec install/vbws_show/lib/vbws_show/show"],
        cwd=workspace, env=dict(os.environ, LD_LIBRARY_PATH=str(Path(prefix) / "lib")),
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert (shown.returncode, shown.stdout.split()) == (0, ["4", "4", "tool", "2"]), shown.stderr

    # The bridge's CDR of messages lcm-gen's classes encoded, and what rclpy should read from it.
    library = TypeLibrary.load([str(lcm_types)], drake=False)
    structs = {known.full_name: known.definition for known in library.types()}
    classes = generate_lcmgen(tmp_path / "lcmgen", lcm_types)
    cases = []
    for name in WORKSPACE_TYPES:
        known = library.get(name)
        message = _lcm_message(name, structs, classes)
        cases.append({
            "type": known.ros_type,
            "cdr": known.to_cdr(message.encode()).hex(),
            "values": expected(message, structs[name], structs),
        })  # fmt: skip
        # rosidl's type hash of the commented files is the one the bridge announces.
        package, _, message_name = str(known.ros_type).split("/")
        description = json.loads((workspace / "install" / package / "share" / package / "msg" /
                                  f"{message_name}.json").read_text())  # fmt: skip
        hashes = {entry["type_name"]: entry["hash_string"] for entry in description["type_hashes"]}
        assert hashes[known.ros_type] == known.rihs01, name
    (tmp_path / "cases.json").write_text(json.dumps(cases))
    # In a process of its own that sources the install space as a user's shell does.
    check = subprocess.run(
        ["bash", "-c", f'source install/setup.bash && exec "{sys.executable}" -c "$0"', READ_BRIDGE_CDR],
        cwd=workspace, env=dict(os.environ, CASES=str(tmp_path / "cases.json")),
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert check.returncode == 0, check.stdout + check.stderr
    written = check.stdout.split()
    assert len(written) == len(cases)
    store = get_typestore(Stores.EMPTY)
    for text_type, text in library.ros_definitions().items():
        store.register(get_types_from_msg(text, text_type))
    for case, back_hex in zip(cases, written, strict=True):
        cdr, back = bytes.fromhex(case["cdr"]), bytes.fromhex(back_hex)
        # rclpy's bytes are the bridge's, but for the alignment padding Fast-CDR leaves unwritten
        # (the bridge writes zeros there): rosbags, which writes zeros too, reads and writes them as the bridge's.
        assert len(back) == len(cdr), case["type"]
        assert all(cdr[index] == 0 for index in range(len(cdr)) if back[index] != cdr[index]), case["type"]
        assert bytes(store.serialize_cdr(store.deserialize_cdr(back, case["type"]), case["type"])) == cdr


def _write_cpp_node(folder: Path) -> None:
    """A C++ package that uses the generated ArmStateT: find_package, the package's targets, and
    the header rosidl names after the message in snake_case."""
    (folder / "src").mkdir(parents=True)
    (folder / "package.xml").write_text(f"""<?xml version="1.0"?>
<package format="3">
  <name>vbws_show</name>
  <version>0.0.0</version>
  <description>Prints a generated message's constant and fields</description>
  <maintainer email="viewer-bridge@example.invalid">viewer-bridge</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <depend>{ROBOT}</depend>
  <export><build_type>ament_cmake</build_type></export>
</package>
""")
    (folder / "CMakeLists.txt").write_text(f"""cmake_minimum_required(VERSION 3.21)
project(vbws_show CXX)
find_package(ament_cmake REQUIRED)
find_package({ROBOT} REQUIRED)
{ros_interfaces.WHEEL_INCLUDES_CMAKE}add_executable(show src/show.cpp)
target_link_libraries(show ${{{ROBOT}_TARGETS}})
install(TARGETS show DESTINATION lib/${{PROJECT_NAME}})
ament_package()
""")
    (folder / "src" / "show.cpp").write_text(f"""#include <iostream>
#include <{ROBOT}/msg/arm_state_t.hpp>

int main() {{
  {ROBOT}::msg::ArmStateT arm;
  arm.tip.frame_id = "tool";
  arm.joint_angles = {{0.5, -0.25}};
  std::cout << {ROBOT}::msg::ArmStateT::MAX_JOINTS << " " << arm.gains.size() << " "
            << arm.tip.frame_id << " " << arm.joint_angles.size() << std::endl;
}}
""")


# Run with the colcon install space sourced (the packages are nowhere else): each case's CDR read by
# rclpy's class is the expected values; what rclpy writes back is printed, in hex.
READ_BRIDGE_CDR = """
import importlib, json, os
from array import array
import numpy as np
from rclpy.serialization import deserialize_message, serialize_message

def plain(value):
    if hasattr(value, "get_fields_and_field_types"):
        return {field: plain(getattr(value, field)) for field in value.get_fields_and_field_types()}
    if isinstance(value, (list, tuple, np.ndarray, array, bytes)):
        return [plain(item) for item in value]
    return value.item() if isinstance(value, np.generic) else value

for case in json.load(open(os.environ["CASES"])):
    package, _, name = case["type"].split("/")
    cls = getattr(importlib.import_module(package + ".msg"), name)
    assert cls.__module__.startswith(package), cls.__module__
    cdr = bytes.fromhex(case["cdr"])
    message = deserialize_message(cdr, cls)
    assert plain(message) == case["values"], (case["type"], plain(message), case["values"])
    print(serialize_message(message).hex())
"""


def test_generate_leaves_a_package_folder_it_did_not_write_untouched_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, it wrote over a folder of the same name and deleted its .msg files."""
    mine = tmp_path / "src" / BASE
    (mine / "msg").mkdir(parents=True)
    (mine / "package.xml").write_text("<package format='3'><name>hand written</name></package>\n")
    (mine / "msg" / "Mine.msg").write_text("# my own\nint32 x\n")
    before = {path: path.read_bytes() for path in sorted(mine.rglob("*")) if path.is_file()}
    with pytest.raises(RosInterfaceError) as raised:
        ros_interfaces.generate_packages(DEFINITIONS, tmp_path / "src")
    assert str(raised.value).startswith(f"{mine} is not a package viewer-bridge generated")
    assert {path: path.read_bytes() for path in sorted(mine.rglob("*")) if path.is_file()} == before
    assert not (tmp_path / "src" / MAIN).exists()  # all or nothing: the other package was not written either
    lab = ["ros-interfaces", "generate", "--lcm-types", str(CORPUS), "-o", str(tmp_path / "src")]
    capsys.readouterr()
    assert main([*lab[:2], "lab_geometry_lcm_msgs", *lab[2:]]) == 0  # beside it: fine
    (tmp_path / "src" / "lab_robot_lcm_msgs").mkdir()
    (tmp_path / "src" / "lab_robot_lcm_msgs" / "notes.txt").write_text("mine\n")
    assert main([*lab[:2], "lab_robot_lcm_msgs", *lab[2:]]) == 2
    error = capsys.readouterr().err
    assert f"{tmp_path / 'src' / 'lab_robot_lcm_msgs'} is not a package viewer-bridge generated" in error
    assert [path.name for path in (tmp_path / "src" / "lab_robot_lcm_msgs").iterdir()] == ["notes.txt"]
    # Its own output, generated again over itself, is fine; an empty folder is taken too.
    (tmp_path / "src" / "lab_robot_lcm_msgs" / "notes.txt").unlink()
    assert main([*lab[:2], "lab_robot_lcm_msgs", *lab[2:]]) == 0
    assert main([*lab[:2], "lab_robot_lcm_msgs", *lab[2:]]) == 0
    assert (tmp_path / "src" / "lab_robot_lcm_msgs" / ros_interfaces.GENERATED_MARK).is_file()
