"""A ROS 2 MCAP written by mcap-ros2-support with standard and custom types, and lcm-gen's own
Python to read LCM back: the ground truth of the ROS 2 -> LCM tests."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tests.lcmcodec.test_from_ros import CUSTOM

CUSTOM_TYPES = ["my_robot/msg/Finger", "my_robot/msg/Gripper"]

_HEADER = {"stamp": {"sec": 1_700_000_000, "nanosec": 123_456_789}, "frame_id": "base_link"}
_POSE = {
    "position": {"x": 1.5, "y": -2.25, "z": 0.125},
    "orientation": {"x": 0.0, "y": 0.0, "z": 0.6, "w": 0.8},
}
_TWIST = {"linear": {"x": 0.5, "y": 0.0, "z": -0.1}, "angular": {"x": 0.0, "y": 0.2, "z": 3.0}}
_FINGER = {"name": "index", "position": [0.1, 0.2, 0.3], "id": 65535}

# (topic, type, message): every message of the bag, in order, a millisecond apart.
SAMPLES: list[tuple[str, str, dict[str, Any]]] = [
    ("/joint_states", "sensor_msgs/msg/JointState",
     {"header": _HEADER, "name": ["shoulder", "elbow", "wrist"], "position": [0.1, -1.2, 3.0],
      "velocity": [], "effort": [1e-9, 2.5, -7.0]}),
    ("/imu", "sensor_msgs/msg/Imu",
     {"header": _HEADER, "orientation": _POSE["orientation"], "orientation_covariance": [0.01 * i for i in range(9)],
      "angular_velocity": {"x": 0.1, "y": 0.2, "z": 0.3}, "angular_velocity_covariance": [-1.0] + [0.0] * 8,
      "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.81}, "linear_acceleration_covariance": [0.5] * 9}),
    ("/odom", "nav_msgs/msg/Odometry",
     {"header": _HEADER, "child_frame_id": "base_footprint",
      "pose": {"pose": _POSE, "covariance": [float(i) for i in range(36)]},
      "twist": {"twist": _TWIST, "covariance": [-float(i) for i in range(36)]}}),
    ("/camera/image", "sensor_msgs/msg/Image",
     {"header": _HEADER, "height": 3, "width": 4, "encoding": "rgb8", "is_bigendian": 0, "step": 12,
      "data": bytes(range(36))}),
    ("/goal", "geometry_msgs/msg/PoseStamped", {"header": _HEADER, "pose": _POSE}),
    ("/joint_states", "sensor_msgs/msg/JointState",
     {"header": {"stamp": {"sec": 2, "nanosec": 4_294_967_295 % 1_000_000_000}, "frame_id": "ünïcode ✓"},
      "name": [], "position": [], "velocity": [], "effort": []}),
    ("/gripper", "my_robot/msg/Gripper",
     {"header": _HEADER, "serial": (1 << 63) - 1, "ticks": 4_294_967_295, "torques": [-32768, 0, 32767],
      "label": "left", "fingers": [_FINGER, {**_FINGER, "name": "thumb", "id": 0}], "thumbs": [_FINGER, _FINGER],
      "targets": [{"x": 1.0, "y": 2.0, "z": 3.0}], "flags": [True, False, True], "c": 65, "blob": b"\x00\xff"}),
]  # fmt: skip


def typestore() -> Any:
    """rosbags' Jazzy store with the custom package registered."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in sorted(CUSTOM.rglob("*.msg")):
        if path.stem != "Note":  # wstring: neither rosbags nor mcap-ros2-support can serialize it
            store.register(get_types_from_msg(path.read_text(), f"my_robot/msg/{path.stem}"))
    return store


def write_bag(path: Path) -> None:
    from mcap_ros2.writer import Writer

    store = typestore()
    with path.open("wb") as stream:
        writer = Writer(stream)
        schemas: dict[str, Any] = {}
        for index, (topic, ros_type, message) in enumerate(SAMPLES):
            if ros_type not in schemas:
                schemas[ros_type] = writer.register_msgdef(
                    ros_type, store.generate_msgdef(ros_type, ros_version=2)[0]
                )
            stamp = 1_000_000_000 + index * 1_000_000
            writer.write_message(topic, schemas[ros_type], message, log_time=stamp, publish_time=stamp)
        writer.finish()


_DECODE = """
import pickle, sys
sys.path.insert(0, sys.argv[1])
import importlib

def plain(value):
    if hasattr(value, "__slots__"):
        return {slot: plain(getattr(value, slot)) for slot in value.__slots__}
    if isinstance(value, (list, tuple)):
        return [plain(item) for item in value]
    return value

out = []
for lcm_name, data in pickle.load(sys.stdin.buffer):
    package, name = lcm_name.split(".")
    out.append(plain(getattr(importlib.import_module(package), name).decode(data)))
sys.stdout.buffer.write(pickle.dumps(out))
"""


def lcmgen_decode(python_dir: Path, messages: list[tuple[str, bytes]]) -> list[Any]:
    """lcm-gen's classes (in `python_dir`) decoding `(LCM full name, bytes)`, as nested dicts. A fresh
    interpreter: lcm-gen's `std_msgs` must not meet the ROS 2 wheels' package of that name."""
    done = subprocess.run([sys.executable, "-c", _DECODE, str(python_dir)], input=pickle.dumps(messages),
                          capture_output=True, check=True)  # fmt: skip
    loaded: list[Any] = pickle.loads(done.stdout)  # noqa: S301 - our own subprocess's output
    return loaded
