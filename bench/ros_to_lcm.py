"""Benchmark: any ROS 2 type's CDR onto LCM (docs/PROTOCOLS.md section 14), the compiled code
against the obvious Python path.

Run: .venv/bin/python bench/ros_to_lcm.py [--quick]

The baseline is what a hand-written ROS 2 -> LCM bridge does: rclpy's `deserialize_message` into
the ROS 2 message, then lcm-gen's Python class of the generated `.lcm` files filled from it and
encoded. lcm-gen's classes are generated with each package renamed (`bench_sensor_msgs`), so
that they do not shadow the ROS 2 wheels' packages of the same names in this process; a package
name is not part of a fingerprint, so the bytes are the same (each row checks that both sides
give the same LCM bytes). Both sides of a row run in this process on the same bytes, in
alternating rounds.
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
import sysconfig
import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import paired, print_measures

from viewer_bridge.lcmcodec.from_ros import LcmFromRos, load_ros_definitions, map_ros_types
from viewer_bridge.lcmcodec.ros_cdr import compile_ros_encoders

TYPES = ["sensor_msgs/msg/JointState", "sensor_msgs/msg/Image"]


def lcmgen_classes(mapping: LcmFromRos, folder: Path) -> dict[str, Any]:
    """lcm-gen's classes of the mapped types, by ROS 2 name, from packages renamed `bench_<pkg>`."""
    packages = {name.split(".")[0] for name in mapping.texts}
    rename = re.compile(rf"\b({'|'.join(sorted(packages))})\b(?=[.;])")
    for full_name, text in mapping.texts.items():
        package, name = full_name.split(".")
        path = folder / "lcm" / f"bench_{package}" / f"{name}.lcm"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(rename.sub(r"bench_\1", text))
    lcm_gen = Path(sysconfig.get_paths()["purelib"]) / "bin" / "lcm-gen"
    subprocess.run([str(lcm_gen), "--python", "--ppath", str(folder / "py"), *map(str, (folder / "lcm").rglob("*.lcm"))],
                   check=True)  # fmt: skip
    sys.path.insert(0, str(folder / "py"))
    try:
        return {
            ros: getattr(importlib.import_module(f"bench_{ros.split('/')[0]}"), ros.split("/")[-1])
            for ros in TYPES
        }
    finally:
        sys.path.remove(str(folder / "py"))


def joint_state(joints: int) -> Any:
    from sensor_msgs.msg import JointState

    rng = np.random.default_rng(0)
    message = JointState(name=[f"joint_{index}" for index in range(joints)], position=rng.normal(size=joints).tolist(),
                         velocity=rng.normal(size=joints).tolist(), effort=rng.normal(size=joints).tolist())  # fmt: skip
    message.header.stamp.sec, message.header.stamp.nanosec, message.header.frame_id = 1_700_000_000, 5, "base"
    return message


def image(width: int, height: int) -> Any:
    from sensor_msgs.msg import Image

    data = np.random.default_rng(1).integers(0, 256, width * height * 3, np.uint8).tobytes()
    message = Image(height=height, width=width, encoding="rgb8", step=width * 3, data=data)
    message.header.frame_id = "camera"
    return message


def baseline(
    cdr: bytes, ros_class: Any, lcm_class: Any, fill: Callable[[Any, Any], None]
) -> Callable[[], bytes]:
    """rclpy's `deserialize_message`, then lcm-gen's class: its header from the ROS 2 one, the rest by `fill`."""
    from rclpy.serialization import deserialize_message

    def build() -> bytes:
        ros = deserialize_message(cdr, ros_class)
        message = lcm_class()
        message.header.stamp.sec, message.header.stamp.nanosec = (
            ros.header.stamp.sec,
            ros.header.stamp.nanosec,
        )
        message.header.frame_id = ros.header.frame_id
        fill(ros, message)
        return message.encode()  # type: ignore[no-any-return]

    return build


def fill_joint_state(ros: Any, message: Any) -> None:
    message.name_length, message.name = len(ros.name), ros.name
    for field in ("position", "velocity", "effort"):
        values = getattr(ros, field)
        setattr(message, f"{field}_length", len(values))
        setattr(message, field, values)  # lcm-gen's encode takes array.array


def fill_image(ros: Any, message: Any) -> None:
    message.height, message.width, message.encoding = ros.height, ros.width, ros.encoding
    message.is_bigendian, message.step = ros.is_bigendian, ros.step
    message.data_length, message.data = len(ros.data), ros.data.tobytes()


def measures(size: Size = Size.FULL) -> list[Measure]:
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Image, JointState

    definitions, wanted = load_ros_definitions(TYPES)
    mapping = map_ros_types(definitions, wanted)
    encoders = compile_ros_encoders(mapping, TYPES)
    with tempfile.TemporaryDirectory() as folder:
        classes = lcmgen_classes(mapping, Path(folder))
    rows = []
    cdr = serialize_message(joint_state(7))
    theirs = baseline(cdr, JointState, classes[TYPES[0]], fill_joint_state)
    generated = compile_ros_encoders(mapping, TYPES[:1], keep_layouts=False)[TYPES[0]]
    for encoder, which, goal in ((encoders[TYPES[0]], "the kept layout (a stream's shape repeats)", 10),
                                 (generated, "a new shape each (the generated code)", 2)):  # fmt: skip
        ours_call = partial(encoder.encode, cdr)
        assert ours_call() == theirs()  # noqa: S101 (the row compares like with like)
        ours, base = paired(ours_call, theirs, size)
        rows.append(Measure(f"sensor_msgs/JointState (7 joints) CDR -> LCM, {which}, vs rclpy + lcm-gen", ours * 1e6,
                            base * 1e6, "us", f"ratio >= {goal}x", base / ours >= goal))  # fmt: skip
    width, height = size.pick(full=(640, 480), quick=(640, 480), smoke=(8, 6))
    cdr = serialize_message(image(width, height))
    ours_call, theirs = (
        partial(encoders[TYPES[1]].encode, cdr),
        baseline(cdr, Image, classes[TYPES[1]], fill_image),
    )
    assert ours_call() == theirs()  # noqa: S101
    ours, base = paired(ours_call, theirs, size)
    rows.append(Measure(f"sensor_msgs/Image ({width}x{height} rgb8) CDR -> LCM, vs rclpy + lcm-gen", ours * 1e6,
                        base * 1e6, "us", "ours <= baseline", ours <= base))  # fmt: skip
    return rows


if __name__ == "__main__":
    print_measures(measures(Size.QUICK if "--quick" in sys.argv[1:] else Size.FULL))
