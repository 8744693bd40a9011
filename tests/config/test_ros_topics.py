"""`ros_topics:` and `--ros-topics` (viewer_bridge/config/bridge.py): nothing by default, a route per
ROS graph the config uses, the topic's channel, and clear errors."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from viewer_bridge.config.bridge import BUILTIN_CONFIGS, destination_name, load_config
from viewer_bridge.errors import ConfigError

DDS_ONLY = """\
ros_topics: ["/joint_states", "/arm/(left|right)/state"]
routes:
  - name: poses
    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}
    translator: drake_to_pose_array
    destination: {transport: ros, name: /poses}
"""


def made(config_routes: list) -> list:  # type: ignore[type-arg]
    return [route for route in config_routes if route.translator == "ros_topic_to_lcm"]


@pytest.mark.parametrize("name", sorted(BUILTIN_CONFIGS))
def test_no_built_in_config_carries_a_topic_onto_lcm(name: str) -> None:
    assert made(load_config(f"builtin:{name}").routes) == []


def test_the_flag_makes_one_route_per_ros_graph_the_config_uses() -> None:
    dds = load_config(None).with_ros_topics(["/joint_states", "/imu/.*"])
    [route] = made(dds.routes)
    assert (route.name, route.source.transport, route.destination.transport) == (
        "ros_topics_ros",
        "ros",
        "lcm",
    )
    assert route.source.name == "((?:/joint_states)|(?:/imu/.*))" and route.destination.name == "{1:lcm}"
    assert [
        r.source.transport for r in made(load_config("builtin:zenoh").with_ros_topics([".*"]).routes)
    ] == ["zenoh"]
    # A config on no ROS graph (Foxglove only): DDS, the default.
    assert [
        r.source.transport for r in made(load_config("builtin:foxglove").with_ros_topics([".*"]).routes)
    ] == ["ros"]
    assert load_config(None).with_ros_topics([]).routes == load_config(None).routes


def test_a_route_is_made_once_however_often_the_config_is_checked_again() -> None:
    config = (
        load_config(None).with_ros_topics(["/a"]).with_settings("lcm", url="udpm://239.255.76.67:7667?ttl=0")
    )
    config = config.with_ros_topics(["/b"]).allowing_commands(["X"]).with_settings("ros", node="other")
    [route] = made(config.routes)
    assert route.source.name == "((?:/a)|(?:/b))"
    assert [r.name for r in config.routes].count("ros_topics_ros") == 1


def test_a_yaml_config_names_them_too(tmp_path: Path) -> None:
    path = tmp_path / "bridge.yaml"
    path.write_text(DDS_ONLY)
    [route] = made(load_config(path).routes)
    pattern = re.compile(route.source.name)
    for topic, channel in [("/joint_states", "joint_states"), ("/arm/left/state", "arm/left/state")]:
        match = pattern.fullmatch(topic)
        assert match is not None and destination_name(route.destination.name, match) == channel
    assert pattern.fullmatch("/joint_states_2") is None and pattern.fullmatch("/arm/up/state") is None
    # The topic is the first group whatever groups the patterns have: a stream per topic.
    assert (
        pattern.fullmatch("/arm/left/state").groups()[0] != pattern.fullmatch("/arm/right/state").groups()[0]
    )  # type: ignore[union-attr]


def test_a_bad_regex_and_a_taken_route_name_are_clear_errors(tmp_path: Path) -> None:
    path = tmp_path / "bridge.yaml"
    path.write_text(DDS_ONLY.replace('"/joint_states"', '"/joint_states("'))
    with pytest.raises(ConfigError) as bad:
        load_config(path)
    assert (
        bad.value.line == 1
        and "ros_topics" in bad.value.key
        and "not a regular expression" in bad.value.reason
    )
    path.write_text(DDS_ONLY.replace("name: poses", "name: ros_topics_ros"))
    with pytest.raises(ConfigError) as taken:
        load_config(path)
    assert taken.value.line == 3 and "the name of the route ros_topics makes" in taken.value.reason
