"""Interface packages generated from `.msg` definitions (tests/ros_interfaces_corpus.py), built
into the venv by `ros_interfaces.build` and checked against real peers: rclpy nodes, rosbags' CDR
and its RIHS01 type hashes, and colcon building the generated sources in a workspace.

The corpus is built once into the venv and kept: later sessions find it current (by the hash of
its sources) and build nothing.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tests.peers import RosProbe
from tests.ros_interfaces_corpus import BASE, DEFINITIONS, MAIN
from viewer_bridge import ros_interfaces
from viewer_bridge.cli import main
from viewer_bridge.errors import RosInterfaceError
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


def test_the_cli_generate_needs_lcm_types(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ros-interfaces", "generate", "-o", "x"]) == 2
    assert "generate needs --lcm-types SRC" in capsys.readouterr().err


@pytest.mark.slow
def test_colcon_builds_the_generated_workspace_and_rclpy_imports_it(tmp_path: Path) -> None:
    """A user's colcon workspace with the generated packages, built against the venv's ROS 2 wheels
    as `ros_interfaces` builds into the venv (the venv is the underlay's ament prefix)."""
    workspace = tmp_path / "ws"
    # Names of their own: the venv holds the corpus's packages built, which must not be what imports.
    definitions = {name.replace("vbtest_", "vbtestws_"): text.replace("vbtest_", "vbtestws_")
                   for name, text in DEFINITIONS.items()}  # fmt: skip
    ros_interfaces.generate_packages(definitions, workspace / "src")
    prefix = sys.prefix
    env = dict(os.environ, AMENT_PREFIX_PATH=prefix, CMAKE_PREFIX_PATH=prefix)
    colcon = Path(sys.executable).parent / "colcon"
    build = subprocess.run(
        [
            str(colcon), "build", "--event-handlers", "console_direct-",
            "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF",
        ],  # fmt: skip
        cwd=workspace,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    install = workspace / "install"
    python_path = [str(path) for path in sorted(install.glob("*/**/python3*/*-packages"))]
    libraries = [str(install / package.replace("vbtest_", "vbtestws_") / "lib") for package in (BASE, MAIN)]
    run_env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([*python_path, os.environ.get("PYTHONPATH", "")]),
        LD_LIBRARY_PATH=os.pathsep.join([*libraries, os.environ.get("LD_LIBRARY_PATH", "")]),
    )
    # In a process of its own: the install space's libraries must be on its loader path at start.
    check = subprocess.run(
        [sys.executable, "-c", ROUND_TRIP], env=run_env, capture_output=True, text=True, timeout=300
    )
    assert check.returncode == 0, check.stdout + check.stderr
    assert check.stdout.split() == ["7", "round-tripped"]


# Run against the colcon install space (the packages are nowhere else).
ROUND_TRIP = """
from rclpy.serialization import deserialize_message, serialize_message
from vbtestws_base_lcm_msgs.msg import Point
from vbtestws_lcm_msgs.msg import JointSample
sample = JointSample(num_joints=JointSample.MAX_JOINTS, velocity=[1.0, -2.5], joint_names=["a", "b"],
                     path=[Point(x=1.0, y=2.0, z=3.0)], ok=True)
sample.blob.data = [1, 2, 255]
back = deserialize_message(serialize_message(sample), JointSample)
assert back == sample, (back, sample)
print(back.num_joints, "round-tripped")
"""
