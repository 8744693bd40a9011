"""Benchmark: any LCM type to ROS 2 CDR and back, the compiled code against the obvious Python path.

Run: .venv/bin/python bench/lcm_generic.py [--quick]

The baseline is what a hand-written bridge does: decode with the lcm-gen'd class, build an rclpy
message, `rclpy.serialization.serialize_message`. For `drake.lcmt_iiwa_status` the rclpy message
is the real `drake_lcm_msgs/msg/LcmtIiwaStatus` when its interface package is built into the venv;
until then it is `sensor_msgs/JointState` carrying three of the seven arrays (a lighter message
than the real one, so the ratio is a lower bound), and the row says which. The same message
converted again and again is what a kept layout (`viewer_bridge/lcmcodec/layout.py`) serves: a
robot's stream repeats its shape. The 100,000-element array is a type of one `double[n]` against
lcm-gen's class and `std_msgs/Float64MultiArray`, against numpy byte-swapping the same 800 kB into
a new array, and against a memcpy of them into new bytes (the floor of any conversion that hands out fresh bytes).
The way back (issue 32): `lcmt_iiwa_command` (7 joints, as Drake's driver takes it) from CDR to
LCM bytes against rclpy's `deserialize_message` into the built `drake_lcm_msgs/LcmtIiwaCommand`
and Drake's lcm-gen'd class filled from it and encoded; the 100,000 doubles against rclpy's
`deserialize_message` of a `Float64MultiArray` and lcm-gen's class. Each row first checks that
both sides give the same LCM bytes. The floor rows put both iiwa conversions next to one bare
`struct` unpack and pack of the same fields, nothing looked up or checked: what converting values
through Python costs at the least, so what bounds the ratio to a hand-written bridge.
Both sides of a row run in this process on the same bytes, in alternating rounds.
"""

from __future__ import annotations

import argparse
import importlib
import struct
import subprocess
import sys
import sysconfig
import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import drake
import numpy as np
from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import paired, print_measures

from viewer_bridge.lcmcodec.library import TypeLibrary

BIG = "package bench;\nstruct big_array_t { int32_t n; double values[n]; }\n"
BIG_SIZE = 100_000


def iiwa_status(joints: int = 7) -> Any:
    message = drake.lcmt_iiwa_status()
    message.utime = 1_700_000_000_000_000
    message.num_joints = joints
    rng = np.random.default_rng(0)
    for name in message.__slots__[2:]:
        setattr(message, name, rng.normal(size=joints).tolist())
    return message


def iiwa_baseline(data: bytes) -> tuple[str, Callable[[], bytes]]:
    """lcm-gen decode + an rclpy message + serialize_message, and the rclpy type's name."""
    from rclpy.serialization import serialize_message

    try:
        real = importlib.import_module("drake_lcm_msgs.msg").LcmtIiwaStatus
    except ImportError:
        real = None
    if real is not None:

        def build_real() -> bytes:
            status = drake.lcmt_iiwa_status.decode(data)
            message = real()
            message.utime, message.num_joints = status.utime, status.num_joints
            for name in status.__slots__[2:]:
                setattr(message, name, getattr(status, name))
            return serialize_message(message)  # type: ignore[no-any-return]

        return "drake_lcm_msgs/LcmtIiwaStatus", build_real
    from sensor_msgs.msg import JointState

    def build_joint_state() -> bytes:
        status = drake.lcmt_iiwa_status.decode(data)
        message = JointState()
        message.header.stamp.sec, micros = divmod(status.utime, 1_000_000)
        message.header.stamp.nanosec = micros * 1000
        message.position = status.joint_position_measured
        message.velocity = status.joint_velocity_estimated
        message.effort = status.joint_torque_measured
        return serialize_message(message)  # type: ignore[no-any-return]

    return "sensor_msgs/JointState (3 of 7 arrays)", build_joint_state


def big_array(folder: Path) -> tuple[TypeLibrary, Any, bytes]:
    """The library knowing `bench.big_array_t`, lcm-gen's class for it, and one message's bytes."""
    (folder / "big.lcm").write_text(BIG)
    lcm_gen = Path(sysconfig.get_paths()["purelib"]) / "bin" / "lcm-gen"
    subprocess.run([str(lcm_gen), "--python", "--ppath", str(folder), str(folder / "big.lcm")], check=True)
    sys.path.insert(0, str(folder))
    try:
        lcmgen_class = importlib.import_module("bench.big_array_t").big_array_t
    finally:
        sys.path.remove(str(folder))
    message = lcmgen_class()
    message.n = BIG_SIZE
    message.values = np.random.default_rng(1).normal(size=BIG_SIZE).tolist()
    return TypeLibrary.load([str(folder / "big.lcm")], drake=False), lcmgen_class, message.encode()


def big_baseline(lcmgen_class: Any, data: bytes) -> Callable[[], bytes]:
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64MultiArray

    def build() -> bytes:
        decoded = lcmgen_class.decode(data)
        message = Float64MultiArray()
        message.data = decoded.values
        return serialize_message(message)  # type: ignore[no-any-return]

    return build


def iiwa_command(joints: int = 7) -> Any:
    message = drake.lcmt_iiwa_command()
    message.utime = 1_700_000_000_000_000
    message.num_joints = message.num_torques = joints
    rng = np.random.default_rng(2)
    message.joint_position = rng.normal(size=joints).tolist()
    message.joint_torque = rng.normal(size=joints).tolist()
    return message


def iiwa_command_baseline(cdr: bytes) -> Callable[[], bytes]:
    """What a hand-written ROS 2 -> LCM bridge does: rclpy's `deserialize_message` into the built
    `drake_lcm_msgs/LcmtIiwaCommand`, then Drake's lcm-gen'd class filled from it and encoded."""
    from drake_lcm_msgs.msg import LcmtIiwaCommand
    from rclpy.serialization import deserialize_message

    def build() -> bytes:
        ros = deserialize_message(cdr, LcmtIiwaCommand)
        message = drake.lcmt_iiwa_command()
        message.utime, message.num_joints, message.num_torques = ros.utime, ros.num_joints, ros.num_torques
        # encode takes arrays
        message.joint_position, message.joint_torque = ros.joint_position, ros.joint_torque
        return message.encode()  # type: ignore[no-any-return]

    return build


def big_back_baseline(lcmgen_class: Any, values: list[float]) -> Callable[[], bytes]:
    """rclpy's `deserialize_message` of a `std_msgs/Float64MultiArray` holding the same doubles,
    and lcm-gen's class filled from it and encoded."""
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import Float64MultiArray

    cdr = serialize_message(Float64MultiArray(data=values))

    def build() -> bytes:
        ros = deserialize_message(cdr, Float64MultiArray)
        message = lcmgen_class()
        message.n, message.values = len(ros.data), ros.data.tolist()
        return message.encode()  # type: ignore[no-any-return]

    return build


def reverse_measures(size: Size, library: TypeLibrary, big_library: TypeLibrary, lcmgen_class: Any,
                     big: bytes) -> list[Measure]:  # fmt: skip
    """Issue 32's speed goal: CDR -> LCM."""
    known = library.get("drake.lcmt_iiwa_command")
    lcm = iiwa_command().encode()
    cdr = known.to_cdr(lcm)
    baseline = iiwa_command_baseline(cdr)
    assert known.from_cdr(cdr) == lcm == baseline()  # noqa: S101 (the rows compare like with like)
    ours, base = paired(partial(known.from_cdr, cdr), baseline, size)
    rows = [Measure("lcmt_iiwa_command (7 joints) CDR -> LCM, vs rclpy deserialize + lcm-gen", ours * 1e6,
                    base * 1e6, "us", "ratio >= 20x", base / ours >= 20)]  # fmt: skip
    floor_way = bare_struct(cdr, "<2s2xqi4x7di4x7d", ">0sqi7di7d")
    assert known.packed_fingerprint + floor_way() == lcm  # noqa: S101 (the floor does the same work)
    ours, floor = paired(partial(known.from_cdr, cdr), floor_way, size)
    rows.append(Measure("lcmt_iiwa_command CDR -> LCM, vs one bare struct unpack + pack of its fields (the floor)",
                        ours * 1e6, floor * 1e6, "us", "ours <= 3x floor", ours <= 3 * floor))  # fmt: skip
    big_known = big_library.get("bench.big_array_t")
    big_cdr = big_known.to_cdr(big)
    values = lcmgen_class.decode(big).values
    big_base = big_back_baseline(lcmgen_class, list(values))
    assert big_known.from_cdr(big_cdr) == big == big_base()  # noqa: S101
    ours, base = paired(partial(big_known.from_cdr, big_cdr), big_base, size)
    rows.append(Measure("double[100000] CDR -> LCM, vs rclpy Float64MultiArray + lcm-gen", ours * 1e3,
                        base * 1e3, "ms", "ratio >= 20x", base / ours >= 20))  # fmt: skip
    return rows


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Issue 31's speed goals 1 and 2 (the throughput goal is the router's, in its own bench), and
    issue 32's (CDR -> LCM)."""
    rows = []
    library = TypeLibrary.load()
    data = iiwa_status().encode()
    known = library.get("drake.lcmt_iiwa_status")
    rclpy_type, baseline = iiwa_baseline(data)
    ours, base = paired(partial(known.to_cdr, data), baseline, size)
    rows.append(Measure(f"lcmt_iiwa_status (7 joints) -> CDR, vs lcm-gen + {rclpy_type}", ours * 1e6, base * 1e6,
                        "us", "ratio >= 20x", base / ours >= 20))  # fmt: skip
    counts_as_padding = "".join("4x7d" if array == 0 else "8x7d" for array in range(7))
    ours, floor = paired(
        partial(known.to_cdr, data), bare_struct(data, ">8sqi49d", "<0sqi" + counts_as_padding), size
    )
    rows.append(Measure("lcmt_iiwa_status -> CDR, vs one bare struct unpack + pack of its fields (the floor)",
                        ours * 1e6, floor * 1e6, "us", "ours <= 3x floor", ours <= 3 * floor))  # fmt: skip
    with tempfile.TemporaryDirectory() as folder:
        big_library, lcmgen_class, big = big_array(Path(folder))
        big_known = big_library.get("bench.big_array_t")
        ours, base = paired(partial(big_known.to_cdr, big), big_baseline(lcmgen_class, big), size)
        rows.append(Measure("double[100000] -> CDR, vs lcm-gen + Float64MultiArray", ours * 1e3, base * 1e3,
                            "ms", "ratio >= 50x", base / ours >= 50))  # fmt: skip
        ours, floor = paired(partial(big_known.to_cdr, big), partial(_numpy_swap, big), size)
        rows.append(Measure("double[100000] -> CDR, vs numpy byteswap into a new array", ours * 1e3, floor * 1e3,
                            "ms", "ours <= 3x numpy", ours <= 3 * floor))  # fmt: skip
        ours, floor = paired(partial(big_known.to_cdr, big), partial(_memcpy, big), size)
        rows.append(Measure("double[100000] -> CDR, vs a memcpy of its bytes", ours * 1e3, floor * 1e3,
                            "ms", "ours <= 3x memcpy", ours <= 3 * floor))  # fmt: skip
        rows += reverse_measures(size, library, big_library, lcmgen_class, big)
    return rows


def bare_struct(data: bytes, read: str, write: str) -> Callable[[], bytes]:
    """One `struct` unpack of every field and one pack the other way, nothing looked up or checked
    (a sequence's count written as zeros): the floor of converting values through Python."""
    unpack_from, pack = struct.Struct(read).unpack_from, struct.Struct(write).pack
    return lambda: pack(*unpack_from(data))


def _numpy_swap(data: bytes) -> Any:
    """The doubles byte-swapped into a new array: numpy's one pass, no header, no bytes object."""
    return np.frombuffer(data, ">f8", BIG_SIZE, 12).astype("<f8")


def _memcpy(data: bytes) -> bytes:
    """The doubles copied into new bytes: what any conversion that hands out fresh bytes costs."""
    return bytes(memoryview(data)[12:])


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="fewer rounds")
    print_measures(measures(Size.QUICK if parser.parse_args().quick else Size.FULL))


if __name__ == "__main__":
    main()
