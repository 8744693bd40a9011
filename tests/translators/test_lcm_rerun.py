"""lcm_to_rerun_scalars: Drake's own LCM types, published by pydrake's classes into a log and
converted into an `.rrd` by builtin:rerun, read back with Rerun's reader: every numeric field is an
entity /lcm/<channel>/<field path> whose scalars equal the message's values at its utime."""

from __future__ import annotations

from collections import defaultdict
from datetime import timedelta
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import lcm
import numpy as np
from rerun.chunk import RrdReader

from viewer_bridge.cli.log_convert import convert
from viewer_bridge.config.bridge import load_config


def _status(step: int) -> Any:
    status = drake_lcmtypes.lcmt_iiwa_status()
    status.utime = 1000 * (step + 1)
    status.num_joints = 7
    for field in status.__slots__[2:]:
        setattr(status, field, [0.1 * step + joint for joint in range(7)])
    return status


def _plan() -> Any:
    plan = drake_lcmtypes.lcmt_robot_plan()
    plan.utime = 5000
    for index in range(2):
        state = drake_lcmtypes.lcmt_robot_state()
        state.utime, state.num_joints = index, 2
        state.joint_name, state.joint_position = ["a", "b"], [0.5 * index, -0.25]
        plan.plan.append(state)
    plan.num_states = 2
    return plan


def test_every_numeric_field_of_any_lcm_channel_plots_at_its_utime(tmp_path: Path) -> None:
    log_path = tmp_path / "bus.lcmlog"
    statuses = [_status(step) for step in range(3)]
    log = lcm.EventLog(str(log_path), "w", overwrite=True)
    for step, status in enumerate(statuses):
        log.write_event(10 + step, "IIWA_STATUS", status.encode())
    log.write_event(20, "PLAN", _plan().encode())
    log.write_event(21, "MYSTERY", b"\x01\x02\x03\x04\x05\x06\x07\x08tail")  # no known type: held, counted
    log.close()
    out = tmp_path / "bus.rrd"
    convert(log_path, out, load_config("builtin:rerun"), progress=False)

    rows: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for chunk in RrdReader(out).stream():
        rows[chunk.entity_path].extend(chunk.to_record_batch().to_pylist())
    lcm_entities = {path for path in rows if path.startswith("/lcm/")}
    assert not any(path.startswith("/lcm/MYSTERY") for path in lcm_entities)
    for field in statuses[0].__slots__:
        series = rows[f"/lcm/IIWA_STATUS/{field}"]
        assert len(series) == 3, field
        for row, status in zip(sorted(series, key=lambda row: row["sim_time"]), statuses, strict=True):
            assert row["sim_time"] == timedelta(microseconds=status.utime)
            expected = getattr(status, field)
            assert np.allclose(row["Scalars:scalars"], expected if isinstance(expected, list) else [expected])
    plan = _plan()
    assert rows["/lcm/PLAN/plan/1/joint_position"][0]["Scalars:scalars"] == plan.plan[1].joint_position
    assert rows["/lcm/PLAN/plan/1/joint_position"][0]["sim_time"] == timedelta(microseconds=5000)
    assert "/lcm/PLAN/plan/0/joint_name" not in rows  # strings are no numbers
