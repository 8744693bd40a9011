"""A pydrake diagram publishing Drake's driver messages as a robot's driver would: an
`LcmPublisherSystem` of `lcmt_iiwa_status` on IIWA_STATUS (every 10 ms) and one of
`lcmt_robot_plan` on ROBOT_PLAN (every 100 ms), their values following sim time.

Run as a script: `python tests/drake_robot_status.py URL SECONDS` (real time, then exits), or
through `drive_until` (until a test's peers have what it waits for).
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import drake as drake_lcmtypes

STATUS_CHANNEL = "IIWA_STATUS"
PLAN_CHANNEL = "ROBOT_PLAN"
JOINTS = 7


def iiwa_status(time_s: float) -> Any:
    message = drake_lcmtypes.lcmt_iiwa_status()
    message.utime = round(time_s * 1e6)
    message.num_joints = JOINTS
    for offset, field in enumerate(message.__slots__[2:]):
        setattr(message, field, [time_s + 0.125 * joint - offset for joint in range(JOINTS)])
    return message


def robot_plan(time_s: float) -> Any:
    plan = drake_lcmtypes.lcmt_robot_plan()
    plan.utime = round(time_s * 1e6)
    plan.num_states = 2
    for index in range(plan.num_states):
        state = drake_lcmtypes.lcmt_robot_state()
        state.utime = plan.utime + index
        state.num_joints = 2
        state.joint_name = ["iiwa_joint_1", "iiwa_joint_2"]
        state.joint_position = [time_s, -float(index)]
        plan.plan.append(state)
    return plan


def run(url: str, seconds: float) -> None:
    from pydrake.common.value import AbstractValue
    from pydrake.lcm import DrakeLcm
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder, LeafSystem
    from pydrake.systems.lcm import LcmPublisherSystem

    class Driver(LeafSystem):  # type: ignore[misc]
        """The messages a driver would send, from sim time."""

        def __init__(self) -> None:
            super().__init__()
            self.DeclareAbstractOutputPort(
                "status", lambda: AbstractValue.Make(iiwa_status(0.0)),
                lambda context, out: out.set_value(iiwa_status(context.get_time())),
            )  # fmt: skip
            self.DeclareAbstractOutputPort(
                "plan", lambda: AbstractValue.Make(robot_plan(0.0)),
                lambda context, out: out.set_value(robot_plan(context.get_time())),
            )  # fmt: skip

    lcm = DrakeLcm(url)
    builder = DiagramBuilder()
    driver = builder.AddSystem(Driver())
    for port, channel, lcm_type, period in (
        ("status", STATUS_CHANNEL, drake_lcmtypes.lcmt_iiwa_status, 0.01),
        ("plan", PLAN_CHANNEL, drake_lcmtypes.lcmt_robot_plan, 0.1),
    ):
        publisher = builder.AddSystem(
            LcmPublisherSystem.Make(channel=channel, lcm_type=lcm_type, lcm=lcm, publish_period=period)
        )
        builder.Connect(driver.GetOutputPort(port), publisher.get_input_port())
    simulator = Simulator(builder.Build())
    simulator.set_target_realtime_rate(1.0)
    simulator.AdvanceTo(seconds)


def drive_until(url: str, arrived: Callable[[], bool], timeout: float = 120.0) -> bool:
    """Drake's driver publishing on `url` (a process of its own) until `arrived()`, then stopped;
    whether it came true within `timeout` seconds.

    Never for a fixed time: the bridge's lazy routes translate only once they see a subscriber,
    and on a loaded machine discovery can take seconds (Fast DDS re-announces a participant it
    missed every 3 s), so a run of fixed length may end before the subscriber matched and leave
    it a few messages."""
    driver = subprocess.Popen([sys.executable, __file__, url, str(timeout + 60)])
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if arrived():
                return True
            if driver.poll() is not None:
                raise AssertionError(f"Drake's driver exited early ({driver.returncode})")
            time.sleep(0.05)
        return arrived()
    finally:
        driver.terminate()
        driver.wait(timeout=30)


if __name__ == "__main__":
    run(sys.argv[1], float(sys.argv[2]))
