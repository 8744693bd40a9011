"""Where a live topic's type comes from (viewer_bridge/lcmcodec/ros_types.py): an installed package's
`.msg` first, else rosbags' Jazzy store; and each type's encoder, or why it has none."""

from __future__ import annotations

from pathlib import Path

from viewer_bridge.lcmcodec.cdr_to_lcm import LcmEncoder
from viewer_bridge.lcmcodec.ros_types import InstalledDefinitions, RosTypesOnLcm, install_prefixes


def installed(prefix: Path, name: str, text: str) -> None:
    package, _, type_name = name.split("/")
    folder = prefix / "share" / package / "msg"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{type_name}.msg").write_text(text)


def test_an_installed_msg_comes_first_then_the_store(tmp_path: Path) -> None:
    installed(tmp_path, "lab_msgs/msg/Probe", "int32 count\nstd_msgs/Header header\nfloat64[] values\n")
    installed(tmp_path, "std_msgs/msg/String", "string data\nint8 extra\n")  # a workspace's own build wins
    definitions = InstalledDefinitions([tmp_path])
    assert [field for field, _ in definitions["lab_msgs/msg/Probe"][1]] == ["count", "header", "values"]
    assert [field for field, _ in definitions["std_msgs/msg/String"][1]] == ["data", "extra"]
    assert "sensor_msgs/msg/JointState" in definitions  # not installed there: the store's
    assert "lab_msgs/msg/Missing" not in definitions


def test_a_msg_rosbags_cannot_read_counts_as_absent(tmp_path: Path) -> None:
    installed(tmp_path, "lab_msgs/msg/Garbled", "float64[ x\n")
    assert "lab_msgs/msg/Garbled" not in InstalledDefinitions([tmp_path])


def test_each_type_gets_its_encoder_or_the_reason(tmp_path: Path) -> None:
    installed(tmp_path, "lab_msgs/msg/Clash", "float64[] x\nint32 x_length\n")
    types = RosTypesOnLcm(InstalledDefinitions([tmp_path]))
    encoder = types.encoder("sensor_msgs/msg/JointState")
    # made once
    assert isinstance(encoder, LcmEncoder) and types.encoder("sensor_msgs/msg/JointState") is encoder
    assert "no installed interface package" in str(types.encoder("lab_msgs/msg/Missing"))
    assert "x_length would collide" in str(types.encoder("lab_msgs/msg/Clash"))


def test_the_prefixes_are_this_environment_and_ament_s() -> None:
    prefixes = install_prefixes({"AMENT_PREFIX_PATH": "/opt/ws/install:/opt/ros/jazzy"})
    assert prefixes[1:] == [Path("/opt/ws/install"), Path("/opt/ros/jazzy")]
