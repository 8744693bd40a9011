"""`dump`'s rendering of any known LCM type: Drake's driver types and a lab's own."""

from __future__ import annotations

import json
import math

import drake

from tests.lcmcodec.corpus import CORPUS
from viewer_bridge.cli.dump import as_json, as_text, describe
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.transports.lcm import LcmEvent


def test_drakes_iiwa_status_by_default() -> None:
    status = drake.lcmt_iiwa_status()
    status.utime, status.num_joints = 9, 2
    for name in status.__slots__[2:]:
        setattr(status, name, [0.5, -0.5])
    record = json.loads(as_json(LcmEvent("IIWA_STATUS", status.encode(), 1_000_000)))
    assert record["type"] == "drake.lcmt_iiwa_status" and record["channel"] == "IIWA_STATUS"
    assert record["message"]["joint_torque_external"] == [0.5, -0.5] and record["message"]["utime"] == 9


def test_a_labs_type_given_a_library_with_bytes_summarised() -> None:
    library = TypeLibrary.load([str(CORPUS)], drake=False)
    codec = library.codecs("lab.robot.arm_state_t")["lab.robot.arm_state_t"]
    arm = codec.message_class(cols=3, blob=b"abc", grid=[], robotName="left")
    event = LcmEvent("LEFT_ARM", codec.encode(arm), 0)
    assert describe(event)["type"] is None  # the default library does not know it
    record = describe(event, library)
    assert record["message"]["robot_name"] == "left" and record["message"]["blob"]["bytes"] == 3
    assert describe(event, library, bytes_summary=False)["message"]["blob"] == {"utf8": "abc"}
    text = as_text(event, library).splitlines()
    assert text[0].endswith("LEFT_ARM lab.robot.arm_state_t (" + str(len(event.data)) + " bytes)")
    assert "  blob: 3 bytes, CRC-32 352441c2" in text
    assert "  tip:" in text and "    frame_id: ''" in text


def test_json_carries_byte_arrays_whole_as_from_json_takes_them_back() -> None:
    library = TypeLibrary.load([str(CORPUS)], drake=False)
    known = library.get("lab.robot.arm_state_t")
    codec = library.codecs("lab.robot.arm_state_t")["lab.robot.arm_state_t"]
    for blob, expected in [(b"abc", {"utf8": "abc"}), (b"\xff\x00\x01", {"base64": "/wAB"})]:
        data = codec.encode(codec.message_class(cols=3, blob=blob, grid=[], robotName="left"))
        record = json.loads(as_json(LcmEvent("LEFT_ARM", data, 0), library))
        assert record["message"]["blob"] == expected
        assert known.from_json(record["message"]) == data


def _refuse(constant: str) -> None:
    raise ValueError(f"not JSON: {constant}")


def test_json_lines_are_strict_json_with_nan_and_infinities_as_strings() -> None:
    status = drake.lcmt_iiwa_status()
    status.utime, status.num_joints = 9, 3
    for name in status.__slots__[2:]:
        setattr(status, name, [0.5, 0.5, 0.5])
    status.joint_position_measured = [math.nan, math.inf, -math.inf]
    line = as_json(LcmEvent("IIWA_STATUS", status.encode(), 1_000_000))
    record = json.loads(line, parse_constant=_refuse)  # Python's parser takes bare NaN unless told not to
    assert record["message"]["joint_position_measured"] == ["NaN", "Infinity", "-Infinity"]
    assert record["message"]["joint_torque_external"] == [0.5, 0.5, 0.5] and record["message"]["utime"] == 9
