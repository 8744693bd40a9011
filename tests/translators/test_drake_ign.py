"""The ign translators' message names: each named once, spelled by the ign transport's `package`
setting, or by a route's own `package` option; and the two built-in configs that set it."""

from __future__ import annotations

import pytest

from viewer_bridge.config.bridge import load_config
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import PROTOBUF, MessageType
from viewer_bridge.transports.ign import IgnSettings, IgnTransport

IGN_TRANSLATORS = {
    "drake_to_ign_model": "Model",
    "drake_to_ign_model_v": "Model_V",
    "drake_to_ign_pose_v": "Pose_V",
    "drake_to_ign_poses_stamped": "PosesStamped",
    "drake_contacts_to_ign_contacts": "Contacts",
}


@pytest.mark.parametrize(("name", "message"), IGN_TRANSLATORS.items())
def test_a_translator_names_its_message_once_and_a_route_may_pick_the_package(
    name: str, message: str
) -> None:
    translator = TRANSLATORS.get(name)
    assert [output.type for output in translator.outputs] == [MessageType(message, PROTOBUF)]
    assert [output.type.name for output in translator({}).outputs] == [message]
    for package in ("gz", "ignition"):
        chosen = translator({"package": package})
        assert [output.type.name for output in chosen.outputs] == [f"{package}.msgs.{message}"]


def test_the_pose_v_reader_names_its_message_once_too() -> None:
    reader = TRANSLATORS.get("ign_pose_v_to_drake_draw")
    assert reader.reads == (MessageType("Pose_V", PROTOBUF),)
    assert reader({"package": "ignition"}).reads == (MessageType("ignition.msgs.Pose_V", PROTOBUF),)


def test_the_transport_carries_short_names_and_both_packages_only() -> None:
    for name in ("Pose_V", "gz.msgs.Pose_V", "ignition.msgs.Contacts"):
        assert IgnTransport.carries(MessageType(name, PROTOBUF)), name
    for name in ("foxglove.SceneUpdate", "geometry_msgs/msg/PoseArray", "my.msgs.Pose_V", "*"):
        assert not IgnTransport.carries(MessageType(name, PROTOBUF)), name
    assert not IgnTransport.carries(MessageType("Pose_V", "cdr"))


def test_gz_is_the_default_package() -> None:
    assert IgnSettings().package == "gz"


def test_builtin_gz_and_ign_differ_only_in_the_package() -> None:
    gz, ign = load_config("builtin:gz"), load_config("builtin:ign")
    assert [route.model_dump() for route in gz.routes] == [route.model_dump() for route in ign.routes]
    assert [route.name for route in gz.routes] == ["model", "pose_v", "poses_stamped", "from_ign"]
    settings = gz.settings("ign"), ign.settings("ign")
    assert isinstance(settings[0], IgnSettings) and isinstance(settings[1], IgnSettings)
    assert (settings[0].package, settings[1].package) == ("gz", "ignition")
    assert (settings[0].partition, settings[0].ip) == (settings[1].partition, settings[1].ip) == (None, None)
