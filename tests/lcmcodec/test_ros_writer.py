"""The generated ROS 2 CDR writer (`lcmcodec/ros_writer.py`) against rosbags, type by type.

Every Jazzy type is written from random values (scalars at their limits, arrays given as lists
and as numpy arrays, sequences of every length up to a few, every alignment a field can meet)
and must give rosbags' bytes exactly; values that are no message of the type are refused with
the type and the field named.
"""

from __future__ import annotations

import random
import tracemalloc
from typing import Any

import numpy as np
import pytest
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

from viewer_bridge.errors import EncodeError, SchemaError
from viewer_bridge.lcmcodec.ros_writer import ros_writer

STORE = get_typestore(Stores.ROS2_JAZZY)
# rosbags packs `byte` and `char` as int8, ROS 2 as an octet: both agree on 0..127.
_INTS = {"int8": (-128, 127), "uint8": (0, 255), "byte": (0, 127), "char": (0, 127),
         "int16": (-(2**15), 2**15 - 1), "uint16": (0, 2**16 - 1), "int32": (-(2**31), 2**31 - 1),
         "uint32": (0, 2**32 - 1), "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1)}  # fmt: skip
_NUMPY = {"int8": "i1", "uint8": "u1", "byte": "u1", "char": "u1", "int16": "i2", "uint16": "u2", "int32": "i4",
          "uint32": "u4", "int64": "i8", "uint64": "u8", "float32": "f4", "float64": "f8", "bool": "?"}  # fmt: skip
TYPES = sorted(name for name, definition in STORE.fielddefs.items() if "wstring" not in str(definition))


class Values:
    """Random values of a type, as the writer takes them and as rosbags' message objects."""

    def __init__(self, seed: int, hashable: bool = False) -> None:
        self.rng = random.Random(seed)
        # Sequences as values a kept stretch may hold: empty ones as `()`, bytes as bytes.
        self.hashable = hashable

    def primitive(self, base: str) -> Any:
        if base == "bool":
            return self.rng.random() < 0.5
        if base in _INTS:
            low, high = _INTS[base]
            return self.rng.choice([low, high, self.rng.randint(low, high)])
        if base == "float32":
            return float(np.float32(self.rng.uniform(-1e6, 1e6)))
        if base == "float64":
            return self.rng.choice([self.rng.uniform(-1e300, 1e300), float("nan"), float("-inf"), -0.0])
        return self.rng.choice(["", "a", "ab", "abc", "héllo", "world_frame"])

    def field(self, description: tuple[Any, Any]) -> tuple[Any, Any]:
        node, value = description
        if node == Nodetype.BASE:
            primitive = self.primitive(value[0])
            return primitive, primitive
        if node == Nodetype.NAME:
            return self.message(value)
        element, bound = value
        count = bound if node == Nodetype.ARRAY else self.rng.randint(0, bound or 4)
        if element[0] == Nodetype.BASE and element[1][0] != "string":
            items = [self.primitive(element[1][0]) for _ in range(count)]
            array = np.array(items, dtype=_NUMPY[element[1][0]])
            if self.hashable and (not count or element[1][0] in ("uint8", "byte", "char", "int8")):
                return (bytes(array) if count else ()), array
            return (items if self.rng.random() < 0.5 else array), array
        pairs = [self.field(element) for _ in range(count)]
        if self.hashable and not count:
            return (), []
        return [ours for ours, _ in pairs], [theirs for _, theirs in pairs]

    def message(self, name: str) -> tuple[Any, Any]:
        _, fields = STORE.fielddefs[name]
        pairs = [self.field(description) for _, description in fields]
        return tuple(ours for ours, _ in pairs), STORE.types[name](*[theirs for _, theirs in pairs])


@pytest.mark.parametrize("seed", range(4))
def test_every_jazzy_type_is_written_as_rosbags_writes_it(seed: int) -> None:
    values = Values(seed)
    for name in TYPES:
        writer = ros_writer(name)
        for _ in range(3):
            ours, theirs = values.message(name)
            assert writer.write(ours) == bytes(STORE.serialize_cdr(theirs, name)), name


@pytest.mark.parametrize("seed", range(2))
def test_stretches_of_strings_and_sequences_are_kept_and_written_again_as_rosbags_writes_them(
    seed: int,
) -> None:
    # Three or more strings and sequences between two runs are kept by their values and position
    # modulo 4 when those are strings, bytes and empty tuples: each value is written twice.
    values = Values(seed, hashable=True)
    for name in TYPES:
        writer = ros_writer(name)
        for _ in range(4):
            ours, theirs = values.message(name)
            reference = bytes(STORE.serialize_cdr(theirs, name))
            assert writer.write(ours) == reference, name
            assert writer.write(ours) == reference, name
    # The same stretch (a status's name, message, hardware id and values) at every position
    # modulo 4: after a status whose last value has 0 to 7 characters.
    status, key_value = (
        STORE.types["diagnostic_msgs/msg/DiagnosticStatus"],
        STORE.types["diagnostic_msgs/msg/KeyValue"],
    )
    ours_statuses: list[Any] = []
    theirs_statuses = []
    for length in range(8):
        ours_statuses += [(1, "arm", "ok", "", [("k", "v" * length)]), (0, "arm", "ok", "", ())]
        theirs_statuses += [
            status(1, "arm", "ok", "", [key_value("k", "v" * length)]),
            status(0, "arm", "ok", "", []),
        ]
    header = STORE.types["std_msgs/msg/Header"](STORE.types["builtin_interfaces/msg/Time"](0, 0), "")
    array = STORE.types["diagnostic_msgs/msg/DiagnosticArray"](header, theirs_statuses)
    reference = bytes(STORE.serialize_cdr(array, "diagnostic_msgs/msg/DiagnosticArray"))
    assert ros_writer("diagnostic_msgs/msg/DiagnosticArray").write((((0, 0), ""), ours_statuses)) == reference


def test_equal_values_in_two_stretches_are_written_each_as_its_own_fields() -> None:
    # Joy's frame id, axes and buttons and WriteSplitEvent's three strings, all at position 0
    # modulo 4, given the same values: "" is an empty sequence in one, an empty string in the other.
    joy = ros_writer("sensor_msgs/msg/Joy").write((((0, 0), ""), "", ""))
    split = ros_writer("rosbag2_interfaces/msg/WriteSplitEvent").write(("", "", ""))
    theirs_joy = STORE.types["sensor_msgs/msg/Joy"](
        STORE.types["std_msgs/msg/Header"](STORE.types["builtin_interfaces/msg/Time"](0, 0), ""),
        np.zeros(0, dtype=np.float32),
        np.zeros(0, dtype=np.int32),
    )
    assert joy == bytes(STORE.serialize_cdr(theirs_joy, "sensor_msgs/msg/Joy"))
    theirs_split = STORE.types["rosbag2_interfaces/msg/WriteSplitEvent"]("", "", "")
    assert split == bytes(STORE.serialize_cdr(theirs_split, "rosbag2_interfaces/msg/WriteSplitEvent"))


def test_kept_stretches_are_bounded_and_stay_right_past_the_bound() -> None:
    # More distinct stretches than are kept (4096), and one longer than is kept (256 bytes): each
    # written as rosbags writes it, the memory kept bounded however many went by.
    writer = ros_writer("rosbag2_interfaces/msg/WriteSplitEvent")
    event = STORE.types["rosbag2_interfaces/msg/WriteSplitEvent"]
    for values in [("a" * 300, "b", "c"), *((f"closed_{k}", f"opened_{k}", "node") for k in range(5000))]:
        reference = bytes(STORE.serialize_cdr(event(*values), "rosbag2_interfaces/msg/WriteSplitEvent"))
        assert writer.write(values) == reference
        assert writer.write(values) == reference
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for k in range(20000):
            writer.write((f"c{k}", f"o{k}", "n"))
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert grown < 8 << 20, grown  # 20,000 stretches kept whole would be well over that


def test_a_kept_stretch_refuses_values_as_the_writer_does() -> None:
    writer = ros_writer("visualization_msgs/msg/Marker")
    texture = (((0, 0), ""), "", b"")
    pose = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    marker: tuple[Any, ...] = (((0, 0), "world"), "ns", 0, 1, 0, pose, (1.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0),
                               (0, 0), False, (), (), "", texture, (), "", "", ("", b""), False)  # fmt: skip
    reference = writer.write(marker)
    assert writer.write(marker) == reference
    with pytest.raises(EncodeError, match=r"Marker\.text: .* contains a NUL character"):
        writer.write(marker[:15] + ("a\0b",) + marker[16:])
    with pytest.raises(
        EncodeError, match=r"Marker\.uv_coordinates\[0\]: expects the fields \(u, v\), got 1 values"
    ):
        writer.write(marker[:14] + (((1.0,),),) + marker[15:])
    assert writer.write(marker) == reference


def test_a_sequence_of_plain_messages_may_be_an_array() -> None:
    points = np.arange(12, dtype=np.float64).reshape(4, 3)
    triangles = np.array([[0, 1, 2], [1, 2, 3]], dtype=np.uint32)
    writer = ros_writer("shape_msgs/msg/Mesh")
    as_tuples = (
        [(row,) for row in triangles.tolist()],
        [tuple(row) for row in points.tolist()],
    )  # one field each
    assert writer.write((triangles, points)) == writer.write(as_tuples)
    mesh = STORE.types["shape_msgs/msg/Mesh"]
    triangle, point = STORE.types["shape_msgs/msg/MeshTriangle"], STORE.types["geometry_msgs/msg/Point"]
    reference = mesh([triangle(row) for row in triangles], [point(*row) for row in points.tolist()])
    assert writer.write((triangles, points)) == bytes(STORE.serialize_cdr(reference, "shape_msgs/msg/Mesh"))


def test_marks_say_where_fields_were_written() -> None:
    writer = ros_writer("tf2_msgs/msg/TFMessage", ("transforms.header.stamp", "transforms.transform"))
    transforms = [
        (((7, 8), "world"), name, ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0))) for name in ("a", "bc", "def")
    ]
    data, marks = writer.write_marked((transforms,))
    payload = memoryview(data)[4:]
    assert len(marks["transforms.transform"]) == len(marks["transforms.header.stamp"]) == 3
    for at in marks["transforms.transform"]:
        assert at % 8 == 0
        assert payload[at : at + 56].cast("d").tolist() == [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]
    for at in marks["transforms.header.stamp"]:
        assert payload[at : at + 8].cast("I").tolist() == [7, 8]
    assert writer.write((transforms,)) == data
    with pytest.raises(EncodeError, match="transforms.child: no such field to mark"):
        ros_writer("tf2_msgs/msg/TFMessage", ("transforms.child",))


def test_strings_of_any_length_count_and_alignment_are_written_as_rosbags_writes_them() -> None:
    # The writer keeps short texts' bytes (by text, for each position modulo 4) up to a bound:
    # short and long texts, more distinct ones than it keeps, one after another at every alignment.
    writer = ros_writer("diagnostic_msgs/msg/KeyValue")
    key_value = STORE.types["diagnostic_msgs/msg/KeyValue"]
    texts = ["", "a", "ab", "abc", "héllo", "x" * 300, *(f"frame_{index}" for index in range(5000))]
    for key, value in zip(texts, texts[1:] + texts[:1], strict=True):
        reference = bytes(STORE.serialize_cdr(key_value(key, value), "diagnostic_msgs/msg/KeyValue"))
        assert writer.write((key, value)) == reference
    with pytest.raises(EncodeError, match=r"KeyValue\.value: a string is expected, not list"):
        writer.write(("key", ["not", "text"]))


def test_an_empty_sequence_may_be_any_empty_value() -> None:
    writer = ros_writer("visualization_msgs/msg/Marker")
    texture = (((0, 0), ""), "", b"")
    pose = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    marker: tuple[Any, ...] = (((0, 0), "world"), "ns", 0, 1, 0, pose, (1.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0),
                               (0, 0), False, [], [], "", texture, [], "", "", ("", b""), False)  # fmt: skip
    reference = writer.write(marker)
    for empty in ((), np.zeros((0, 3))):
        assert writer.write(marker[:10] + (empty,) + marker[11:]) == reference
    with pytest.raises(EncodeError, match=r"Marker\.points: a sequence is expected, not int"):
        writer.write(marker[:10] + (0,) + marker[11:])


@pytest.mark.parametrize(
    ("value", "field", "reason"),
    [
        ((((1, 2), "wor\0ld"), 0, 0, "", False, 0, b""), "header.frame_id", "contains a NUL character"),
        ((((1, 2), "\ud800"), 0, 0, "", False, 0, b""), "header.frame_id", "not valid Unicode"),
        ((((1, 2), 5), 0, 0, "", False, 0, b""), "header.frame_id", "a string is expected, not int"),
        ((((2**31, 0), "w"), 0, 0, "", False, 0, b""), "header.stamp.sec", "is no int32"),
        ((((1, 2), "w"), -1, 0, "", False, 0, b""), "height", "is no uint32"),
        ((((1, 2), "w"), 0.5, 0, "", False, 0, b""), "height", "is no uint32"),
        ((((1, 2), "w"), 0, 0, "", False, 0, [1, 256]), "data", "outside uint8's range"),
        ((((1, 2), "w"), 0, 0, "", False, 0, np.ones(3)), "data", "integers are expected, not float64"),
        ((((1, 2), "w"), 0, 0, "", False, 0, 7), "data", "a sequence of numbers is expected, not int"),
        (((1, 2), 0, 0, "", False, 0, b""), "header.stamp", "expects the fields (sec, nanosec), got a int"),
        (
            (((1, 2, 3), "w"), 0, 0, "", False, 0, b""),
            "header.stamp",
            "expects the fields (sec, nanosec), got 3",
        ),
        ((((1, 2), "w"), 0, 0), "(message)", "expects the fields (header, height, width, encoding"),
    ],
)
def test_values_that_are_no_message_are_refused_by_field(value: Any, field: str, reason: str) -> None:
    with pytest.raises(EncodeError) as caught:
        ros_writer("sensor_msgs/msg/Image").write(value)
    assert caught.value.type_name == "sensor_msgs/msg/Image"
    assert caught.value.field == field
    assert reason in caught.value.reason


def test_nested_errors_name_the_element() -> None:
    writer = ros_writer("visualization_msgs/msg/MarkerArray")
    marker = ros_writer("visualization_msgs/msg/Marker")
    texture = (((0, 0), ""), "", b"")
    good = (((0, 0), "world"), "ns", 0, 1, 0, ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)), (1.0, 1.0, 1.0),
            (1.0, 1.0, 1.0, 1.0), (0, 0), False, [], [], "", texture, [], "", "", ("", b""), False)  # fmt: skip
    marker.write(good)
    bad_point = good[:10] + ([(0.0, 0.0, 0.0), (0.0, "x", 0.0)],) + good[11:]
    with pytest.raises(EncodeError, match=r"MarkerArray\.markers\[1\]\.points\[1\]\.y: 'x' is no float64"):
        writer.write(([good, bad_point],))
    short_point = good[:10] + ([(0.0, 0.0)],) + good[11:]
    with pytest.raises(EncodeError, match=r"markers\[0\]\.points\[0\]: expects the fields \(x, y, z\)"):
        writer.write(([short_point],))
    with pytest.raises(EncodeError, match=r"Marker\.points: an N x 3 array is expected"):
        marker.write(good[:10] + (np.zeros((2, 4)),) + good[11:])


def test_fixed_arrays_and_bounded_sequences_are_checked() -> None:
    info = ros_writer("sensor_msgs/msg/CameraInfo")
    header = ((0, 0), "camera")
    roi = (0, 0, 0, 0, False)
    fine = (header, 480, 640, "plumb_bob", [0.0] * 5, [0.0] * 9, [0.0] * 9, [0.0] * 12, 0, 0, roi)
    info.write(fine)
    with pytest.raises(EncodeError, match=r"CameraInfo\.k: a fixed array of 9 elements is given 8"):
        info.write(fine[:5] + ([0.0] * 8,) + fine[6:])
    with pytest.raises(EncodeError, match=r"CameraInfo\.p: a fixed array of 12 elements is given 13"):
        info.write(fine[:7] + (np.zeros(13),) + fine[8:])
    primitive = ros_writer("shape_msgs/msg/SolidPrimitive")
    primitive.write((1, [1.0, 2.0, 3.0], ([],)))
    with pytest.raises(EncodeError, match="4 elements, more than the sequence's bound of 3"):
        primitive.write((1, [1.0, 2.0, 3.0, 4.0], ([],)))


def test_an_unknown_type_is_a_schema_error() -> None:
    with pytest.raises(SchemaError, match="no_such_msgs/msg/Nothing"):
        ros_writer("no_such_msgs/msg/Nothing")


def test_defaults_and_fields_by_name_are_rosbags_defaults() -> None:
    from viewer_bridge.formats.ros.messages import make, to_cdr

    for name in TYPES:
        writer = ros_writer(name)
        assert writer.write(writer.default) == writer.write_fields({}) == to_cdr(make(name)), name
    plane = ros_writer("shape_msgs/msg/Plane")
    assert plane.write_fields({"coef": [0.0, 0.0, 1.0, -2.0]}) == to_cdr(
        make("shape_msgs/msg/Plane", coef=[0, 0, 1, -2])
    )
    with pytest.raises(EncodeError, match=r"Plane\.normal: no such field"):
        plane.write_fields({"normal": [0.0, 0.0, 1.0]})
