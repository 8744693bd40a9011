"""The ign/gz message schema: our fields are Debian's ign-msgs 8 fields; type names in both packages."""

from __future__ import annotations

from types import ModuleType

import numpy as np

from tests.formats.ign.oracle import poses_stamped
from viewer_bridge.formats.ign.schema import MESSAGES, spellings, type_name, wire_type_name
from viewer_bridge.model.scene import LinkPoses


def test_our_fields_are_debians_fields(debian_ign_msgs: ModuleType) -> None:
    """Every field we declare has the number and type Debian's .proto files give it."""
    for name, cls in MESSAGES.classes.items():
        if name == "PosesStamped":  # removed from the .proto files in 2017; Debian has none
            continue
        theirs = getattr(debian_ign_msgs, name).DESCRIPTOR
        assert theirs.full_name == f"ignition.msgs.{name}"
        for field in cls.DESCRIPTOR.fields:
            other = theirs.fields_by_name[field.name]
            assert (field.number, field.type, field.is_repeated) == (
                other.number,
                other.type,
                other.is_repeated,
            ), field.full_name


def test_gz_and_ignition_packages() -> None:
    assert MESSAGES.Pose_V.DESCRIPTOR.full_name == "gz.msgs.Pose_V"
    assert type_name("Model_V", "ignition") == "ignition.msgs.Model_V"
    assert type_name("Model_V", "gz") == "gz.msgs.Model_V"
    # A short name takes the transport's package; a full one (a route's own choice) stays.
    assert wire_type_name("Pose_V", "gz") == "gz.msgs.Pose_V"
    assert wire_type_name("Pose_V", "ignition") == "ignition.msgs.Pose_V"
    assert wire_type_name("ignition.msgs.Pose_V", "gz") == "ignition.msgs.Pose_V"
    assert wire_type_name("gz.msgs.Pose_V", "ignition") == "gz.msgs.Pose_V"
    both = {"gz.msgs.Pose_V", "ignition.msgs.Pose_V"}
    assert spellings("gz.msgs.Pose_V") == spellings("ignition.msgs.Pose_V") == both
    assert spellings("foxglove.SceneUpdate") == {"foxglove.SceneUpdate"}
    assert spellings("my.msgs.Pose_V") == {"my.msgs.Pose_V"}
    stamped = poses_stamped(
        LinkPoses(1500, ("a",), np.zeros(1, np.int32), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]]))
    )
    assert (stamped.time.sec, stamped.time.nsec) == (1, 500_000_000)
    fields = {f.name: f.number for f in stamped.DESCRIPTOR.fields}
    assert fields == {"header": 1, "time": 2, "pose": 3}
