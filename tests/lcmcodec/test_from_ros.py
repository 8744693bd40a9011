"""ROS 2 types onto LCM (docs/PROTOCOLS.md section 14): the mapping, and lcm-gen reading its files."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import SCRIPTS
from viewer_bridge.cli.main import main
from viewer_bridge.lcmcodec.from_ros import load_ros_definitions, map_ros_types

CUSTOM = Path(__file__).parent / "ros_msgs"


def lcm_gen_all(lcm_dir: Path, out: Path) -> subprocess.CompletedProcess[str]:
    """lcm-gen's Python, C, C++ and Java from every .lcm file under `lcm_dir`."""
    for kind in ("py", "c", "cpp", "java"):
        (out / kind).mkdir(parents=True)
    files = sorted(str(path) for path in lcm_dir.rglob("*.lcm"))
    assert files
    return subprocess.run(
        [str(SCRIPTS / "lcm-gen"), "-p", "--ppath", str(out / "py"), "-c", "--c-cpath", str(out / "c"),
         "--c-hpath", str(out / "c"), "-x", "--cpp-hpath", str(out / "cpp"), "-j", "--jpath", str(out / "java"),
         *files],
        capture_output=True, text=True, check=False,
    )  # fmt: skip


def test_lcm_gen_takes_the_standard_sets_and_a_custom_package(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sources = ["sensor_msgs", "geometry_msgs", "nav_msgs", "std_msgs", str(CUSTOM)]
    assert main(["lcm-types", "generate", "--ros-types", *sources, "-o", str(tmp_path / "lcm")]) == 0
    said = capsys.readouterr()
    written = said.out.split()
    assert said.err == f"viewer-bridge lcm-types: wrote {len(written)} types into {tmp_path / 'lcm'}\n"
    assert str(tmp_path / "lcm" / "sensor_msgs" / "JointState.lcm") in written
    assert str(tmp_path / "lcm" / "my_robot" / "Gripper.lcm") in written
    # nested, from another package
    assert str(tmp_path / "lcm" / "builtin_interfaces" / "Time.lcm") in written
    done = lcm_gen_all(tmp_path / "lcm", tmp_path / "gen")
    assert done.returncode == 0, done.stderr
    assert "error" not in (done.stdout + done.stderr).lower()
    assert (tmp_path / "gen" / "py" / "my_robot" / "Gripper.py").exists()
    assert (tmp_path / "gen" / "c" / "sensor_msgs_JointState.h").exists()
    assert (tmp_path / "gen" / "cpp" / "nav_msgs" / "Odometry.hpp").exists()
    assert (tmp_path / "gen" / "java" / "geometry_msgs" / "PoseStamped.java").exists()


def test_the_custom_type_maps_field_by_field() -> None:
    definitions, wanted = load_ros_definitions([str(CUSTOM)])
    mapping = map_ros_types(definitions, wanted)
    assert not mapping.refused
    text = mapping.texts["my_robot.Gripper"]
    for line in [
        "package my_robot;",
        "const int16_t MODE_OPEN = 1;",  # lcm-gen takes no byte constant
        "// uint64 BIG = 18446744073709551615 (no LCM constant can hold it)",
        "// string GREETING = 'hi' (no LCM constant can hold it)",
        "const int8_t ENABLED = 1;",
        "const float HALF = 0.5;",
        "std_msgs.Header header;",
        "int64_t serial;  // ROS 2 uint64, values from 2^63 up are refused",
        "int64_t ticks;  // ROS 2 uint32",
        "int32_t torques_length;",
        "int16_t torques[torques_length];  // at most 4 elements",
        "my_robot.Finger fingers[fingers_length];",
        "my_robot.Finger thumbs[2];",
        "geometry_msgs.Point targets[targets_length];  // at most 3 elements",
        "boolean flags[flags_length];",
        "byte c;  // ROS 2 char",
        "byte blob[blob_length];",
    ]:
        assert line in text, line
    assert "count" in text and "5;" not in text.split("count")[1].split("\n")[0]  # no default value
    assert "string note;  // ROS 2 wstring" in mapping.texts["my_robot.Note"]
    assert "int32_t id;  // ROS 2 uint16" in mapping.texts["my_robot.Finger"]


def test_fingerprints_are_lcm_gens(tmp_path: Path) -> None:
    definitions, wanted = load_ros_definitions(["sensor_msgs/msg/JointState", str(CUSTOM)])
    mapping = map_ros_types(definitions, wanted)
    mapping.write(tmp_path / "lcm")
    assert lcm_gen_all(tmp_path / "lcm", tmp_path / "gen").returncode == 0
    names = ["sensor_msgs/msg/JointState", "my_robot/msg/Gripper", "my_robot/msg/Note"]
    script = "; ".join(
        [f"import sys; sys.path.insert(0, {str(tmp_path / 'gen' / 'py')!r})"]
        + [
            f"from {name.split('/')[0]} import {name.split('/')[-1]} as m; print(m._get_packed_fingerprint().hex())"
            for name in names
        ]  # fmt: skip
    )
    # A fresh interpreter: lcm-gen's `std_msgs` must not meet the ROS 2 wheels' package of that name.
    printed = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout
    assert printed.split() == [mapping.packed_fingerprint(name).hex() for name in names]


def write_msg(folder: Path, name: str, text: str) -> Path:
    path = folder / "lab" / "msg" / f"{name}.msg"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_a_length_field_collision_refuses_the_type_and_those_nesting_it(tmp_path: Path) -> None:
    write_msg(tmp_path, "Clash", "float64[] x\nint32 x_length\n")
    write_msg(tmp_path, "Outer", "Clash inner\n")
    write_msg(tmp_path, "Fine", "float64[] x\nint32 y\n")
    definitions, wanted = load_ros_definitions([str(tmp_path)])
    mapping = map_ros_types(definitions, wanted)
    assert "x_length would collide with field x_length" in mapping.refused["lab/msg/Clash"]
    assert "lab/msg/Clash is refused" in mapping.refused["lab/msg/Outer"]
    assert list(mapping.structs) == ["lab/msg/Fine"]


def test_a_python_keyword_field_and_an_unknown_type_are_refused(tmp_path: Path) -> None:
    write_msg(tmp_path, "Keyword", "int32 lambda\n")
    definitions, wanted = load_ros_definitions([str(tmp_path)])
    mapping = map_ros_types(definitions, [*wanted, "nope_msgs/msg/Missing"])
    assert "Python keyword" in mapping.refused["lab/msg/Keyword"]
    assert "no definition" in mapping.refused["nope_msgs/msg/Missing"]
    assert not mapping.structs


def test_the_command_names_what_it_refuses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_msg(tmp_path, "Clash", "float64[] x\nint32 x_length\n")
    assert main(["lcm-types", "generate", "--ros-types", str(tmp_path), "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert "lab/msg/Clash not mapped: field x's length field" in err
    assert (
        err.splitlines()[-1]
        == f"viewer-bridge lcm-types: wrote 0 types into {tmp_path / 'out'}, 1 type left out (above)"
    )
    assert main(["lcm-types", "generate", "--ros-types", "no_such_msgs", "-o", str(tmp_path / "out")]) == 2
    bad = write_msg(tmp_path / "bad", "Broken", "float64[ x\n")
    assert main(["lcm-types", "generate", "--ros-types", str(bad), "-o", str(tmp_path / "out")]) == 2
    assert f"{bad}: not a .msg definition rosbags reads" in capsys.readouterr().err


def test_constants_are_what_lcm_gen_takes_or_a_comment(tmp_path: Path) -> None:
    write_msg(tmp_path, "Consts", "float64 BIG=1e20\nfloat32 HUGE=1e39\nint64 LOW=-9223372036854775808\n"
              "uint32 U=4294967295\nbyte B=255\nint32 x\n")  # fmt: skip
    definitions, wanted = load_ros_definitions([str(tmp_path)])
    mapping = map_ros_types(definitions, wanted)
    text = mapping.texts["lab.Consts"]
    assert "const double BIG = 1e20;" in text and "const int64_t U = 4294967295;" in text
    assert "// float32 HUGE = 1e39 (no LCM constant: 1e39 is out of float's (float32's) range)" in text
    mapping.write(tmp_path / "lcm")
    done = lcm_gen_all(tmp_path / "lcm", tmp_path / "gen")
    assert done.returncode == 0, done.stderr
