"""The LCM type store (`viewer_bridge.lcm_types`): lookups, one class per type, and on every corpus
type the round trips decode/encode, to_dict/from_dict and to_cdr/from_cdr, held to lcm-gen's
classes and to the ROS 2 form the codec tests expect."""

from __future__ import annotations

import base64
import json
import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, given, settings

import viewer_bridge
from tests.lcmcodec.corpus import CORPUS, TRANSLATOR_CORPUS, expected, generate_lcmgen, lcmgen_messages
from viewer_bridge.errors import DecodeError, EncodeError, JsonValueError, UnknownName
from viewer_bridge.lcmcodec.library import LcmType
from viewer_bridge.lcmcodec.schema import StructDef
from viewer_bridge.typestore import LcmTypes, lcm_types

ARM = "vbtest_lab.arm_status_t"
POINT = "vbtest_geo.point3_t"


@pytest.fixture(scope="module")
def store() -> LcmTypes:
    return lcm_types(TRANSLATOR_CORPUS, drake=False)


def _arm(store: LcmTypes) -> Any:
    point = store.get(POINT)
    return store.get(ARM)(
        utime=7, numJoints=2, jointAngles=[0.5, -1.5], rows=2, cols=1, gainMatrix=[[1.0], [2.0]],
        jointNames=["shoulder", "elbow"], enabled=True, rawBlob=b"\xff\x00", toolTip=point(x=1.0, y=2.0, z=3.0),
        waypoints=[point(), point(z=4.0)], flags=[1, 2, 3],
    )  # fmt: skip


def test_the_package_names_the_store_lazily() -> None:
    assert viewer_bridge.lcm_types is lcm_types


def test_types_and_get(store: LcmTypes) -> None:
    assert {ARM, POINT, "vbtest_lab.tree_node_t", "drake.lcmt_viewer_draw"} <= set(store.types)
    assert list(store.types) == sorted(store.types)
    assert store.get("vbtest_lab_lcm_msgs/msg/ArmStatusT") is store.get(ARM)  # by its ROS 2 type too
    with pytest.raises(KeyError, match="vbtest_lab.nothing_t"):  # callers that catch KeyError still do
        store.get("vbtest_lab.nothing_t")
    # every method that takes a type's name: one typed error, naming the closest known type
    for call in (lambda name: store.from_cdr(b"", name), lambda name: store.from_dict({}, name),
                 lambda name: store.decode(b"", name), lambda name: store.to_dict(b"", name)):  # fmt: skip
        with pytest.raises(
            UnknownName, match=r"^unknown LCM or ROS 2 type 'vbtest_lab.arm_statu_t' .did you mean"
        ):
            call("vbtest_lab.arm_statu_t")


def test_a_nested_type_has_one_class_wherever_it_is_nested(store: LcmTypes) -> None:
    point = store.get(POINT)
    arm = _arm(store)
    assert type(store.decode(store.encode(arm)).toolTip) is point
    assert store.library.codecs(POINT)[POINT].message_class is store.library.codecs(ARM)[POINT].message_class
    # drake.lcmt_point has the same shape, so the same fingerprint: the first by name, unless named
    assert store.decode(store.encode(point(x=2.0)), POINT) == point(x=2.0)
    assert store.decode(store.encode(point(x=2.0))) == store.get("drake.lcmt_point")(x=2.0)


def test_stores_of_one_type_share_its_class_and_another_definitions_is_refused(
    store: LcmTypes, tmp_path: Path
) -> None:
    other = lcm_types(TRANSLATOR_CORPUS, drake=False)  # the same types: the same classes (one registry)
    assert other.get(ARM) is store.get(ARM)
    assert store.decode(store.encode(_arm(other))) == _arm(store)
    (tmp_path / "point.lcm").write_text("package vbtest_geo; struct point3_t { double x; }")
    foreign = lcm_types(tmp_path, drake=False).get(POINT)  # another type of the same name
    with pytest.raises(EncodeError, match=f"{POINT}.<message>: not a message of this store"):
        store.encode(foreign())
    arm = _arm(store)
    arm.toolTip = foreign()
    with pytest.raises(EncodeError, match="toolTip: expected vbtest_geo.point3_t"):
        store.encode(arm)


def test_the_viewer_codecs_and_a_store_share_classes_and_nan_round_trips(store: LcmTypes) -> None:
    """One registry: a message decoded with `codecs.DRAW` is one the store encodes, and the other
    way; NaN and infinities pass both ways unless the strict decoder is asked for."""
    from viewer_bridge.lcmcodec.codecs import DRAW

    message = DRAW.message_class(timestamp=3, num_links=1, link_name=["a"], robot_num=[0],
                                 position=[[math.nan, 0.0, math.inf]], quaternion=[[1.0, 0.0, 0.0, 0.0]])  # fmt: skip
    data = DRAW.encode(message)
    decoded = DRAW.decode(data)
    assert math.isnan(decoded.position[0][0]) and decoded.position[0][2] == math.inf
    assert DRAW.encode(decoded) == data
    assert store.encode(decoded) == data
    assert type(store.decode(data)) is DRAW.message_class
    assert DRAW.encode(store.decode(data)) == data
    with pytest.raises(DecodeError, match=r"position\[0\]\[0\] at byte 30: non-finite value nan"):
        DRAW.strict.decode(data)
    assert DRAW.strict.message_class is DRAW.message_class and DRAW.strict.lenient is DRAW


def test_a_dict_has_the_ros_2_names_flat_arrays_and_json_ready_bytes(store: LcmTypes) -> None:
    data = store.encode(_arm(store))
    value = store.to_dict(data)
    assert value["joint_angles"] == [0.5, -1.5] and value["gain_matrix"] == [1.0, 2.0]
    assert value["tool_tip"] == {"x": 1.0, "y": 2.0, "z": 3.0} and value["raw_blob"] == {"base64": "/wA="}
    assert store.from_dict(json.loads(json.dumps(value)), ARM) == data
    value["raw_blob"] = {"utf8": "hi"}
    assert store.decode(store.from_dict(value, ARM)).rawBlob == b"hi"


def test_errors_name_fields_the_ros_2_way(store: LcmTypes) -> None:
    data = store.encode(_arm(store))
    cut = 8 + 8 + 4 + 4  # in the middle of jointAngles
    for convert in (store.to_dict, store.to_cdr):
        with pytest.raises(DecodeError) as caught:
            convert(data[:cut])
        assert caught.value.field == "joint_angles", caught.value
    with pytest.raises(DecodeError) as decoded:  # decode names the class's attributes: LCM's names
        store.decode(data[:cut])
    assert decoded.value.field == "jointAngles"
    with pytest.raises(JsonValueError) as refused:
        store.from_dict({"joint_angles": [0.5, "x"]}, ARM)
    assert refused.value.field == "joint_angles[1]"
    with pytest.raises(DecodeError, match="names no known type"):
        store.decode(bytes(16))


def test_a_type_with_no_ros_2_form_decodes_but_has_no_dict_or_cdr(store: LcmTypes) -> None:
    node = store.get("vbtest_lab.tree_node_t")
    data = store.encode(node(value=1, numChildren=1, children=[node(value=2)]))
    assert store.decode(data).children[0].value == 2
    with pytest.raises(DecodeError, match="no ROS 2 form"):
        store.to_cdr(data)
    with pytest.raises(JsonValueError, match="no ROS 2 form"):
        store.from_dict({}, "vbtest_lab.tree_node_t")


def _ints(value: Any) -> Any:
    """A dict of `to_dict`, its byte arrays as lists of ints, as the codec tests' `expected` has them."""
    if isinstance(value, dict) and set(value) in ({"utf8"}, {"base64"}):
        raw = value["utf8"].encode() if "utf8" in value else base64.b64decode(value["base64"])
        return list(raw)
    if isinstance(value, dict):
        return {key: _ints(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_ints(item) for item in value]
    return value


def _finite(value: Any) -> bool:
    if isinstance(value, dict):
        return all(map(_finite, value.values()))
    if isinstance(value, list):
        return all(map(_finite, value))
    return not isinstance(value, float) or math.isfinite(value)


def _round_trips(
    store: LcmTypes, known: LcmType, structs: dict[str, StructDef], classes: dict[str, type]
) -> None:
    name = known.full_name

    @settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
    @given(lcmgen_messages(known.definition, structs, classes))
    def check(message: Any) -> None:
        data = message.encode()
        assert store.encode(store.decode(data, name)) == data
        if known.refused is not None:
            return
        assert store.from_cdr(store.to_cdr(data, name), name) == data
        value = store.to_dict(data, name)
        assert _ints(value) == expected(type(message).decode(data), known.definition, structs)
        assume(_finite(value))  # from_dict refuses what JSON cannot say: NaN and infinities
        assert store.from_dict(json.loads(json.dumps(value)), name) == data

    check()


@pytest.mark.parametrize("corpus", [CORPUS, TRANSLATOR_CORPUS], ids=["lcmtypes_corpus", "translators_corpus"])
def test_every_corpus_type_round_trips(corpus: Path, tmp_path_factory: pytest.TempPathFactory) -> None:
    classes = generate_lcmgen(tmp_path_factory.mktemp("lcmgen"), corpus)
    store = lcm_types(corpus, drake=False)
    structs = {name: store.library.get(name).definition for name in store.types}
    assert classes
    for name in classes:
        _round_trips(store, store.library.get(name), structs, classes)
