"""The command line's options as one record (viewer_bridge/config/options.py): `run`, `play`,
`layout` and `convert` turn their arguments into a `RunOptions`, and `config_of` applies it in one
call, giving the config the options applied one by one give."""

from __future__ import annotations

import argparse
from collections.abc import Callable

import pytest

from viewer_bridge.cli import play, run
from viewer_bridge.cli.arguments import split_ros_args
from viewer_bridge.cli.main import _parser
from viewer_bridge.config.bridge import BridgeConfig, load_config
from viewer_bridge.config.options import RunOptions, config_of
from viewer_bridge.errors import UsageError

URL = "udpm://239.255.76.67:7667?ttl=0"


def parsed(words: list[str]) -> argparse.Namespace:
    """`words` as `viewer-bridge` parses them (its --ros-args split off first)."""
    words, ros_args = split_ros_args(words)
    args = _parser()[0].parse_args(words)
    args.ros_args = ros_args
    return args


# A command line, and the config its options make applied one at a time (as `run` did before).
CASES: list[tuple[list[str], Callable[[], BridgeConfig]]] = [
    (["run"], lambda: load_config(None)),
    (
        ["run", "-c", "builtin:foxglove", "--set", "foxglove.port=0", "--lcm-url", URL],
        lambda: load_config("builtin:foxglove").with_settings("lcm", url=URL).with_settings("foxglove", port=0),
    ),
    (
        ["run", "--lcm-types", "my_types", "--lcm-types", "other.module", "--allow-commands", "WSG_.*",
         "--allow-commands", "IIWA_COMMAND", "--ros-topics", "/joint_states", "--ros-topics", "/imu/.*"],
        lambda: load_config(None).with_lcm_types(["my_types", "other.module"])
        .allowing_commands(["WSG_.*", "IIWA_COMMAND"]).with_ros_topics(["/joint_states", "/imu/.*"]),
    ),
    (
        ["run", "--set", "time=sim", "--set", "commands.max_age_ms=500", "--set", "ros.namespace=/sim1",
         "--set", "workers=2"],
        lambda: load_config(None).with_keys(time="sim").with_settings("commands", max_age_ms=500)
        .with_settings("ros", namespace="/sim1").with_keys(workers=2),
    ),
    (
        ["run", "--set", "lcm.url=" + URL, "--ros-args", "-r", "__node:=other", "--"],
        lambda: load_config(None).with_settings("lcm", url=URL).with_settings("ros", ros_args=["-r", "__node:=other"]),
    ),
    (
        ["play", __file__, "-c", "builtin:foxglove", "--set", "foxglove.port=0"],
        lambda: load_config("builtin:foxglove").with_settings("foxglove", port=0),
    ),
]  # fmt: skip


def options_of(args: argparse.Namespace) -> RunOptions:
    """The record the command's own code makes of its arguments."""
    if args.command == "run":
        return run.run_options(args)
    assert args.command == "play"
    return play.run_options(args)


@pytest.mark.parametrize(("words", "one_by_one"), CASES, ids=[" ".join(words) for words, _ in CASES])
def test_the_options_applied_in_one_call_make_the_config_they_made_one_by_one(
    words: list[str], one_by_one: Callable[[], BridgeConfig]
) -> None:
    config = config_of(options_of(parsed(words)))
    expected = one_by_one()
    assert config.model_dump() == expected.model_dump()
    assert [route.name for route in config.routes] == [route.name for route in expected.routes]
    assert {name: config.settings(name) for name in config.transports()} == {
        name: expected.settings(name) for name in expected.transports()
    }


def test_the_record_is_frozen_and_empty_options_change_nothing() -> None:
    options = RunOptions()
    with pytest.raises(AttributeError):
        options.config = "builtin:zenoh"  # type: ignore[misc]
    assert config_of(options).model_dump() == load_config(None).model_dump()


def test_a_bad_set_says_which_option(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(UsageError, match=r"^--set 'port': expected TRANSPORT.KEY=VALUE"):
        config_of(RunOptions(settings=["port"]))
    with pytest.raises(
        UsageError, match=r"^--set foxglove.port=abc: foxglove.port: Input should be a valid integer"
    ):
        config_of(RunOptions(config="builtin:foxglove", settings=["foxglove.port=abc"]))
    config_of(RunOptions(config="builtin:foxglove", settings=["zenoh.mode=client"], ros_args=["-r", "a:=b"]))
    assert capsys.readouterr().err.splitlines() == [
        "viewer-bridge run: warning: --set zenoh.mode=client does nothing: no route of builtin:foxglove uses "
        "the zenoh transport (its routes use: lcm, foxglove)",
        "viewer-bridge run: warning: --ros-args does nothing: no route of builtin:foxglove uses the ros "
        "transport (its routes use: lcm, foxglove)",
    ]
