"""What the config check refuses at start, with the fix: patterns that can never match, misspelt keys."""

from __future__ import annotations

from pathlib import Path

import pytest

from viewer_bridge.config.bridge import load_config
from viewer_bridge.errors import ConfigError
from viewer_bridge.transports.command_policy import (
    alternatives,
    channel_pattern_problem,
    topic_pattern_problem,
)


def test_alternatives_split_only_at_the_top_level() -> None:
    assert alternatives(r"a|(b|c)|[|]|\||^d") == ["a", "(b|c)", "[|]", r"\|", "d"]
    assert alternatives(r"[]|]x|y") == ["[]|]x", "y"]


@pytest.mark.parametrize(
    "pattern", ["/joint_states", "/lab/.*", ".*", "(/a|/b)", "/imu|/joint_states", "[/]x"]
)
def test_a_topic_pattern_that_can_match_passes(pattern: str) -> None:
    assert topic_pattern_problem(pattern) is None


@pytest.mark.parametrize("pattern", ["IIWA_COMMAND", "WSG_.*", "arm/cmd", ".*", "(/x)"])
def test_a_channel_pattern_that_can_match_passes(pattern: str) -> None:
    assert channel_pattern_problem(pattern) is None


def test_a_config_with_a_pattern_that_never_matches_is_refused_with_its_line(tmp_path: Path) -> None:
    config = tmp_path / "c.yaml"
    config.write_text("routes: []\nros_topics:\n  - joint_states\n")
    with pytest.raises(ConfigError, match=r"c\.yaml:2: ros_topics.*did you mean '/joint_states'\?"):
        load_config(config)
    config.write_text("routes: []\ncommands:\n  allow: [IIWA_COMMAND, /lcm_in/WSG_COMMAND]\n")
    with pytest.raises(ConfigError, match=r"commands\.allow.*did you mean 'WSG_COMMAND'\?"):
        load_config(config)


@pytest.mark.parametrize(
    ("key", "meant"), [("rouets", "routes"), ("ros_topic", "ros_topics"), ("foxglov", "foxglove")]
)
def test_a_misspelt_top_level_key_is_named_with_the_one_it_means(
    tmp_path: Path, key: str, meant: str
) -> None:
    config = tmp_path / "c.yaml"
    config.write_text(f"lcm: {{}}\n{key}: []\n")
    with pytest.raises(
        ConfigError, match=rf"c\.yaml:2: {key}: unknown key '{key}' \(did you mean '{meant}'\?\)"
    ):
        load_config(config)
