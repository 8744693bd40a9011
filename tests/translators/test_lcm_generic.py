"""`lcm_to_ros` (viewer_bridge/translators/lcm_generic.py): any known LCM type as CDR of its ROS 2
mapping. Types that are not in lcmtypes/ (a lab's corpus in lcm_corpus/: camelCase names, arrays
sized by fields, a two-dimensional one, strings, bytes, a nested type of another package, and a
recursive type) and Drake's own (pydrake's `drake` module). The CDR is read by an independent
reader, mcap-ros2-support's decoder built from the definition the output carries, and every value
must equal lcm-gen's own decode of the same bytes."""

from __future__ import annotations

import importlib
import json
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import pytest
from mcap_ros2._dynamic import generate_dynamic

from tests.conftest import SCRIPTS
from viewer_bridge.errors import DecodeError, Held, NotAnLcmType
from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.shared import Shared
from viewer_bridge.translators.lcm_generic import LcmToRos
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import CDR, MessageType, Received

CORPUS = Path(__file__).parent / "lcm_corpus"


@pytest.fixture(scope="module")
def corpus() -> TypeLibrary:
    return TypeLibrary.load([str(CORPUS)], drake=False)


@pytest.fixture(scope="module")
def drake_types() -> TypeLibrary:
    return TypeLibrary.load()  # no sources: the project's, and Drake's because pydrake is here


@pytest.fixture(scope="module")
def lcmgen_corpus(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, type]]:
    """lcm-gen's own Python classes of the corpus, by full name."""
    out = tmp_path_factory.mktemp("corpus_lcmgen")
    files = sorted(str(path) for path in CORPUS.rglob("*.lcm"))
    subprocess.run([str(SCRIPTS / "lcm-gen"), "--python", "--ppath", str(out), *files], check=True)
    sys.path.insert(0, str(out))  # the generated decoders import their nested packages by name
    try:
        lab, geo = importlib.import_module("vbtest_lab"), importlib.import_module("vbtest_geo")
        yield {f"vbtest_lab.{name}": getattr(lab, name) for name in ("arm_status_t", "tree_node_t")} | {
            "vbtest_geo.point3_t": geo.point3_t
        }
    finally:
        sys.path.remove(str(out))


def snake(name: str) -> str:
    """The mapping's field names: an upper-case letter after a lower-case one or a digit starts a word."""
    return re.sub(r"(?<=[a-z0-9])([A-Z])", r"_\1", name).lower()


def flat(value: Any, depth: int) -> list[Any]:
    items = list(value)
    for _ in range(depth - 1):
        items = [inner for outer in items for inner in outer]
    return items


def assert_same(lcm: Any, ros: Any, path: str = "") -> None:
    """Every field of lcm-gen's message equals the ROS message's (snake_case, arrays flattened)."""
    cls = type(lcm)
    for name, typename, dims in zip(cls.__slots__, cls.__typenames__, cls.__dimensions__, strict=True):
        mine, theirs = getattr(lcm, name), getattr(ros, snake(name))
        where = f"{path}.{name}"
        if dims:
            mine, theirs = flat(mine, len(dims)), list(theirs)
            assert len(mine) == len(theirs), where
            if "." in typename:
                for index, (a, b) in enumerate(zip(mine, theirs, strict=True)):
                    assert_same(a, b, f"{where}[{index}]")
            else:
                assert [_plain(v) for v in mine] == [_plain(v) for v in theirs], where
        elif "." in typename:
            assert_same(mine, theirs, where)
        else:
            assert _plain(mine) == _plain(theirs), where


def _plain(value: Any) -> Any:
    return value.item() if hasattr(value, "item") else value


def translate(library: TypeLibrary, data: bytes, channel: str = "CHANNEL") -> tuple[MessageType, bytes]:
    translator = LcmToRos(shared=Shared(library))
    message = Received(channel, data)
    translator.observe(message)
    [(index, payload)] = translator.translate(message)
    return translator.outputs[index].type, payload


def ros_decode(message_type: MessageType, payload: bytes) -> Any:
    """mcap-ros2-support's decoder for the schema text the output carries (what a Foxglove client
    or an MCAP reader gets), not the bridge's."""
    assert message_type.definition is not None
    return generate_dynamic(message_type.name, message_type.definition.ros2msg)[message_type.name](payload)


def arm_status(classes: dict[str, type]) -> Any:
    point = classes["vbtest_geo.point3_t"]
    message = classes["vbtest_lab.arm_status_t"]()
    message.utime = 1_700_000_000_123_456
    message.numJoints = 3
    message.jointAngles = [0.25, -1.5, 3.125]
    message.rows, message.cols = 2, 3
    message.gainMatrix = [[1.5, -2.25, 3.0], [4.0, 5.5, -6.75]]  # exact in float32
    message.jointNames = ["shoulder", "elbow", "wrist ü"]
    message.enabled = True
    message.rawBlob = b"\x00\xff"
    message.toolTip = point()
    message.toolTip.x, message.toolTip.y, message.toolTip.z = 0.5, 0.25, -0.125
    message.waypoints = [point(), point()]
    message.waypoints[1].z = 9.0
    message.flags = [1, -2, 2**31 - 1]
    return message


def test_a_labs_type_reaches_ros_with_every_value_as_lcm_gen_decodes_it(
    corpus: TypeLibrary, lcmgen_corpus: dict[str, type]
) -> None:
    data = arm_status(lcmgen_corpus).encode()
    message_type, payload = translate(corpus, data)
    assert message_type == MessageType("vbtest_lab_lcm_msgs/msg/ArmStatusT", CDR)
    assert message_type.definition is not None and message_type.definition.rihs01.startswith("RIHS01_")
    assert "MSG: vbtest_geo_lcm_msgs/Point3T" in message_type.definition.ros2msg  # nested across packages
    decoded = ros_decode(message_type, payload)
    assert_same(lcmgen_corpus["vbtest_lab.arm_status_t"].decode(data), decoded)
    assert list(decoded.gain_matrix) == [1.5, -2.25, 3.0, 4.0, 5.5, -6.75]  # row-major, as LCM's wire
    assert (decoded.rows, decoded.cols) == (2, 3)  # the shape is kept


def test_drakes_own_types_need_no_flag(drake_types: TypeLibrary) -> None:
    status = drake_lcmtypes.lcmt_iiwa_status()
    status.utime, status.num_joints = 42, 7
    for field in status.__slots__[2:]:
        setattr(status, field, [0.1 * joint + len(field) for joint in range(7)])
    plan = drake_lcmtypes.lcmt_robot_plan()
    plan.num_states = 2
    plan.plan = []
    for index in range(2):
        state = drake_lcmtypes.lcmt_robot_state()
        state.utime, state.num_joints = index, 2
        state.joint_name, state.joint_position = ["a", "b"], [index, -index]
        plan.plan.append(state)
    for message, name in ((status, "LcmtIiwaStatus"), (plan, "LcmtRobotPlan")):
        data = message.encode()
        message_type, payload = translate(drake_types, data)
        assert message_type.name == f"drake_lcm_msgs/msg/{name}"
        assert_same(type(message).decode(data), ros_decode(message_type, payload))


def test_a_channel_whose_type_changes_gets_an_output_per_type(drake_types: TypeLibrary) -> None:
    translator = TRANSLATORS.get("lcm_to_ros")(shared=Shared(drake_types))
    status, command = drake_lcmtypes.lcmt_iiwa_status(), drake_lcmtypes.lcmt_iiwa_command()
    indices = []
    for message in (status, command, status):
        received = Received("IIWA_COMMAND", message.encode())
        translator.observe(received)
        [(index, _)] = translator.translate(received)
        indices.append(index)
    assert indices == [0, 1, 0]
    assert [output.type.name for output in translator.outputs] == [
        "drake_lcm_msgs/msg/LcmtIiwaStatus",
        "drake_lcm_msgs/msg/LcmtIiwaCommand",
    ]
    assert {output.suffix for output in translator.outputs} == {""}  # one topic: the channel's


def test_unknown_and_recursive_types_are_held_by_kind_and_named(
    corpus: TypeLibrary, lcmgen_corpus: dict[str, type]
) -> None:
    translator = LcmToRos(shared=Shared(corpus))
    node = lcmgen_corpus["vbtest_lab.tree_node_t"]()
    with pytest.raises(Held) as refused:
        translator.observe(Received("TREE", node.encode()))
    assert refused.value.kind == "refused_type" and "vbtest_lab.tree_node_t" in str(refused.value)
    assert any("vbtest_lab.tree_node_t" in warning for warning in corpus.warnings)
    with pytest.raises(Held) as unknown:  # Drake's types are not loaded in this library
        translator.observe(Received("PANDA", drake_lcmtypes.lcmt_panda_status().encode()))
    assert unknown.value.kind == "unknown_type"
    assert translator.outputs == ()  # nothing announced for either
    message_type, _ = translate(corpus, arm_status(lcmgen_corpus).encode())  # the others go on
    assert message_type.name == "vbtest_lab_lcm_msgs/msg/ArmStatusT"


# --- back: ros_to_lcm ---------------------------------------------------------------------------------


def back(
    library: TypeLibrary, payload: bytes, message_type: MessageType | None, channel: str = "/lcm_in/X"
) -> bytes:
    translator = TRANSLATORS.get("ros_to_lcm")(shared=Shared(library))
    [(index, data)] = translator.translate(Received(channel, payload, message_type=message_type))
    assert translator.outputs[index].type == MessageType("*", "lcm")
    return data


def test_cdr_of_every_corpus_type_comes_back_as_lcm_gens_bytes(
    corpus: TypeLibrary, drake_types: TypeLibrary, lcmgen_corpus: dict[str, type]
) -> None:
    """The outward CDR (checked above against an independent reader) read back: lcm-gen's exact
    bytes, fingerprint first, for a lab's type (two-dimensional, nested, strings, bytes) and Drake's."""
    plan = drake_lcmtypes.lcmt_robot_plan()
    plan.num_states = 1
    state = drake_lcmtypes.lcmt_robot_state()
    state.num_joints, state.joint_name, state.joint_position = 1, ["ü"], [0.5]
    plan.plan = [state]
    for library, message in ((corpus, arm_status(lcmgen_corpus)), (drake_types, plan)):
        data = message.encode()
        message_type, cdr = translate(library, data)
        assert back(library, cdr, message_type) == data


def test_json_comes_back_as_lcm_gens_bytes(drake_types: TypeLibrary) -> None:
    command = drake_lcmtypes.lcmt_iiwa_command()
    command.utime, command.num_joints, command.joint_position = 5, 2, [0.5, -1.0]
    value = {"utime": 5, "num_joints": 2, "joint_position": [0.5, -1.0], "num_torques": 0, "joint_torque": []}
    data = back(
        drake_types, json.dumps(value).encode(), MessageType("drake_lcm_msgs/msg/LcmtIiwaCommand", "json")
    )
    assert data == command.encode()


def test_a_type_that_is_no_lcm_type_or_no_type_at_all_is_refused_naming_topic_and_type(
    drake_types: TypeLibrary,
) -> None:
    with pytest.raises(
        NotAnLcmType, match=r"/lcm_in/POSES: geometry_msgs/msg/PoseArray is no generated LCM type"
    ):
        back(drake_types, b"\0\1\0\0", MessageType("geometry_msgs/msg/PoseArray", CDR), "/lcm_in/POSES")
    with pytest.raises(NotAnLcmType, match="/lcm_in/X: the transport gave no message type"):
        back(drake_types, b"\0\1\0\0", None)


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        (b"{not json", "not JSON"),
        (b"\xff\xfe", "not JSON"),
        (b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    ],
)
def test_text_that_is_not_json_is_a_decode_error(drake_types: TypeLibrary, text: bytes, reason: str) -> None:
    with pytest.raises(DecodeError, match=reason):
        back(drake_types, text, MessageType("drake_lcm_msgs/msg/LcmtIiwaCommand", "json"))


def test_bad_cdr_is_a_decode_error_naming_the_field(drake_types: TypeLibrary) -> None:
    command = drake_lcmtypes.lcmt_iiwa_command()
    command.utime, command.num_joints, command.joint_position = 5, 2, [0.5, -1.0]
    message_type, cdr = translate(drake_types, command.encode())
    for bad in (cdr[:-3], cdr + bytes(8)):
        with pytest.raises(DecodeError):
            back(drake_types, bad, message_type)
    wrong = bytearray(cdr)
    # num_joints (after the header and utime) says 3; the sequence holds 2
    wrong[12:16] = (3).to_bytes(4, "little")
    with pytest.raises(DecodeError, match="num_joints|joint_position"):
        back(drake_types, bytes(wrong), message_type)
