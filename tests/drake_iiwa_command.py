"""A pydrake diagram listening as a robot's driver would: an `LcmSubscriberSystem` of
`lcmt_iiwa_command` on IIWA_COMMAND, with an `LcmInterfaceSystem` handling the bus while the
simulator runs. Says "listening" once subscribed, then, when a command has reached the
subscriber's output, prints its fields as one JSON line and exits (1 after SECONDS without one).

Run as a script: `python tests/drake_iiwa_command.py URL SECONDS`.
"""

from __future__ import annotations

import json
import sys

import drake as drake_lcmtypes

CHANNEL = "IIWA_COMMAND"


def run(url: str, seconds: float) -> int:
    from pydrake.lcm import DrakeLcm
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.lcm import LcmInterfaceSystem, LcmSubscriberSystem

    lcm = DrakeLcm(url)
    builder = DiagramBuilder()
    builder.AddSystem(LcmInterfaceSystem(lcm))
    subscriber = builder.AddSystem(
        LcmSubscriberSystem.Make(channel=CHANNEL, lcm_type=drake_lcmtypes.lcmt_iiwa_command, lcm=lcm)
    )
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(1.0)
    print("listening", flush=True)
    step = 0.05
    while simulator.get_context().get_time() < seconds:
        simulator.AdvanceTo(simulator.get_context().get_time() + step)
        context = subscriber.GetMyContextFromRoot(simulator.get_context())
        command = subscriber.get_output_port().Eval(context)
        if command.utime != 0:  # the port's value before any message is a default-constructed one
            fields = ("utime", "num_joints", "joint_position", "num_torques", "joint_torque")
            print(json.dumps({name: _plain(getattr(command, name)) for name in fields}), flush=True)
            return 0
    return 1


def _plain(value: object) -> object:
    return list(value) if isinstance(value, (list, tuple)) else value


if __name__ == "__main__":
    sys.exit(run(sys.argv[1], float(sys.argv[2])))
