"""tf2_msgs, built into the venv by `viewer-bridge ros-interfaces install`, against real rclpy nodes.

`./dev test` builds it before the tests run; these check that the built package is the real
ROS 2 Jazzy type (its RIHS01 hash as a peer sees it in discovery) and that it carries bytes
serialized by rosbags, as it would a real ROS 2 peer's TF.
"""

from __future__ import annotations

import sys
import time
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

from tests.peers import RosProbe
from viewer_bridge.cli.main import main
from viewer_bridge.ros_build import interfaces as ros_interfaces

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)

TFMESSAGE_HASH = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
PYPROJECT = Path(__file__).parents[2] / "pyproject.toml"


@pytest.fixture
def probes() -> Iterator[tuple[RosProbe, RosProbe]]:
    """Two nodes, each in a context of its own: a publisher's side and a peer's."""
    assert ros_interfaces.missing() == [], "run `viewer-bridge ros-interfaces install` (./dev test does)"
    first, second = RosProbe("tf_publisher"), RosProbe("tf_peer")
    yield first, second
    first.close()
    second.close()


def test_tf2_msgs_is_importable_from_the_venv() -> None:
    from tf2_msgs.msg import TF2Error, TFMessage

    assert TFMessage().transforms == []
    assert (TF2Error.LOOKUP_ERROR, TF2Error.TRANSFORM_ERROR) == (1, 6)
    assert ros_interfaces.missing() == []


def test_a_peer_sees_the_jazzy_type_hash_of_a_tf_publisher(probes: tuple[RosProbe, RosProbe]) -> None:
    source, peer = probes
    topic = "/vb_test/tf_hash"
    source.publisher(topic, "tf2_msgs/msg/TFMessage")

    def found() -> list[Any]:
        return peer.node.get_publishers_info_by_topic(topic)

    assert peer.wait_for(lambda: len(found()) == 1, timeout=60), "the peer never discovered the publisher"
    info = found()[0]
    assert info.topic_type == "tf2_msgs/msg/TFMessage"
    assert str(info.topic_type_hash) == TFMESSAGE_HASH == TYPESTORE.hash_rihs01("tf2_msgs/msg/TFMessage")


def test_cdr_bytes_from_rosbags_arrive_as_the_same_tf(probes: tuple[RosProbe, RosProbe]) -> None:
    source, peer = probes
    topic = "/vb_test/tf_raw"
    received = peer.subscribe(topic, "tf2_msgs/msg/TFMessage")
    publisher = source.publisher(topic, "tf2_msgs/msg/TFMessage")
    assert source.wait_for(lambda: publisher.get_subscription_count() == 1, timeout=60)

    store = TYPESTORE.types
    transforms = [
        store["geometry_msgs/msg/TransformStamped"](
            header=store["std_msgs/msg/Header"](
                stamp=store["builtin_interfaces/msg/Time"](sec=12, nanosec=345_000_000 + index),
                frame_id="world",
            ),
            child_frame_id=f"plant::link_{index}",
            transform=store["geometry_msgs/msg/Transform"](
                translation=store["geometry_msgs/msg/Vector3"](x=1.5 * index, y=-2.25, z=3.0),
                rotation=store["geometry_msgs/msg/Quaternion"](x=0.0, y=0.6, z=0.0, w=0.8),
            ),
        )
        for index in range(3)
    ]
    raw = TYPESTORE.serialize_cdr(
        store["tf2_msgs/msg/TFMessage"](transforms=transforms), "tf2_msgs/msg/TFMessage"
    )
    publisher.publish(bytes(raw))
    assert peer.wait_for(lambda: len(received) >= 1, timeout=60), "the raw TF never arrived"

    got = received[0].transforms
    assert [t.child_frame_id for t in got] == [f"plant::link_{index}" for index in range(3)]
    for index, transform in enumerate(got):
        assert transform.header.frame_id == "world"
        assert (transform.header.stamp.sec, transform.header.stamp.nanosec) == (12, 345_000_000 + index)
        translation, rotation = transform.transform.translation, transform.transform.rotation
        assert (translation.x, translation.y, translation.z) == (1.5 * index, -2.25, 3.0)
        assert (rotation.x, rotation.y, rotation.z, rotation.w) == (0.0, 0.6, 0.0, 0.8)


def test_a_second_install_does_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    start = time.monotonic()
    assert main(["ros-interfaces", "install"]) == 0
    assert time.monotonic() - start < 2
    assert capsys.readouterr().err == ""
    assert main(["ros-interfaces", "status"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"tf2_msgs: installed in {sys.prefix}"
    # Then every other package built into the venv: the LCM types' (./dev test builds drake_lcm_msgs).
    others = [name for name in ros_interfaces.built() if name != "tf2_msgs"]
    assert "drake_lcm_msgs" in others
    assert lines[1:] == [f"{name}: installed (LCM types) in {sys.prefix}" for name in others]


def test_an_unknown_package_exits_2_naming_it(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["ros-interfaces", "install", "no_such_msgs"]) == 2
    assert "unknown interface package no_such_msgs" in capsys.readouterr().err


def test_the_generated_sources_match_rosbags_definitions() -> None:
    assert (
        ros_interfaces.message_text("tf2_msgs/msg/TFMessage")
        == "geometry_msgs/TransformStamped[] transforms\n"
    )
    for name, interface in ros_interfaces.INTERFACES.items():
        used = {
            package for message in interface.messages for package in _packages_used(f"{name}/msg/{message}")
        }
        assert set(interface.depends) == used - {name}
        package = ros_interfaces.interface_package(name)
        xml, cmake = ros_interfaces.package_xml(package), ros_interfaces.cmake_lists(package)
        assert all(f"<depend>{depend}</depend>" in xml for depend in interface.depends)
        assert all(f'"{file}"' in cmake for file in interface.files())
        assert f"DEPENDENCIES {' '.join(interface.depends)}" in cmake


def _packages_used(typename: str) -> set[str]:
    """The packages of the message types a type's fields name (directly)."""
    packages = set()
    for _, desc in TYPESTORE.fielddefs[typename][1]:
        node, arg = desc[1][0] if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE) else desc
        if node == Nodetype.NAME:
            packages.add(str(arg).split("/")[0])
    return packages


def test_the_build_wheels_are_the_ros_build_extra() -> None:
    extras = tomllib.loads(PYPROJECT.read_text())["project"]["optional-dependencies"]
    assert tuple(extras["ros-build"]) == ros_interfaces.BUILD_WHEELS
    assert "viewer-bridge[ros-build]" in extras["all"] and "viewer-bridge[all]" in extras["test"]
