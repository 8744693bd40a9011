"""What a command line says about the config: which one to load, and what it overrides of it.

A command that routes (`run`, `play`, `layout`, `convert`) turns its arguments into one
`RunOptions` and hands it to `config_of`, which loads the config and applies the options in one
place, in the order the command line has always applied them: `--lcm-types`, `--allow-commands`,
`--ros-topics`, `--lcm-url`, each `--set` in turn, then `--ros-args`. A mistake in an option is a
`UsageError` naming the option; an option for a transport that no route uses is a warning.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from dataclasses import dataclass

import yaml

from viewer_bridge.config.bridge import BUILTIN_CONFIGS, BridgeConfig, load_config, routes_on
from viewer_bridge.errors import ConfigError, UsageError
from viewer_bridge.util.extras import TRANSPORT_EXTRAS, lacking


@dataclass(frozen=True)
class RunOptions:
    """A command line's options about the config, as parsed (`--set` as written: `TRANSPORT.KEY=VALUE`)."""

    config: str | None = None  # `-c`: a YAML file or `builtin:NAME`; None: the built-in default
    # With no `-c`: the built-in config less the routes this install lacks the extras of (`run`,
    # `play`; see `builtin_for_this_install`); else the built-in default as written.
    this_install: bool = False
    lcm_types: Sequence[str] = ()  # `--lcm-types`, after the config's `lcm_types`
    allow_commands: Sequence[str] = ()  # `--allow-commands`, widening the config's `commands.allow`
    ros_topics: Sequence[str] = ()  # `--ros-topics`, after the config's `ros_topics`
    lcm_url: str | None = None  # `--lcm-url`: the lcm transport's `url`
    settings: Sequence[str] = ()  # `--set`, applied in order
    ros_args: Sequence[str] = ()  # `--ros-args ...`: the ros transport's `ros_args`


def config_of(options: RunOptions) -> BridgeConfig:
    """The config `options` name, with their overrides applied (raises `ConfigError` for the
    config, `UsageError` for an option)."""
    named, without = (
        builtin_for_this_install()
        if options.config is None and options.this_install
        else (options.config, [])
    )
    config = (
        load_config(named, without=without)
        .with_lcm_types(list(options.lcm_types))
        .allowing_commands(list(options.allow_commands))
        .with_ros_topics(list(options.ros_topics))
    )
    if options.lcm_url:
        config = config.with_settings("lcm", url=options.lcm_url)
    for setting in options.settings:
        config = _with_setting(config, setting, named)
    if options.ros_args:
        _uses(config, "ros", "--ros-args", named)
        config = config.with_settings("ros", ros_args=list(options.ros_args))
    return config


# The transports' names in the line that says which routes were left out.
_SAID = {"ros": "ROS 2", "foxglove": "Foxglove", "zenoh": "Zenoh", "rerun": "Rerun", "ign": "ign-transport"}
# The built-in configs tried, in order, when the default one has no route this install can run.
_FALLBACKS = ("foxglove", "zenoh", "rerun", "ign")


def builtin_for_this_install() -> tuple[str | None, list[str]]:
    """The built-in config to run when none is named (`-c`), and the transports to leave out of it.

    One rule for every extra: the default config's routes on a transport whose extra is not
    installed are left out, said in one line naming them and the extra that adds them. When none is
    left (`[zenoh]` alone, say), the first built-in config whose every transport is installed runs
    instead, said in one line; with none (the core alone), a `MissingExtra` names the extras. A
    config the user names runs as written, or stops naming what it lacks."""
    routes = yaml.safe_load(BUILTIN_CONFIGS["default"])["routes"]
    used = dict.fromkeys(
        end["transport"] for route in routes for end in (route["source"], route["destination"])
    )
    absent = {name: module for name in used if (module := lacking(name)) is not None}
    if not absent:
        return None, []
    kept = [route for route in routes if not any(routes_on(route, name) for name in absent)]
    extras = ",".join(dict.fromkeys(TRANSPORT_EXTRAS[name] for name in absent))
    needs = f"{' and '.join(absent.values())}, not installed: pip install 'viewer-bridge[{extras}]'"
    say = logging.getLogger(__name__).warning
    if kept:
        dropped = " and ".join(
            f"{sum(routes_on(route, name) for route in routes)} {_SAID.get(name, name)} routes"
            for name in absent
        )
        say("viewer-bridge: the built-in config's %s left out: they need %s", dropped, needs)
        return None, list(absent)
    for name in _FALLBACKS:
        document = yaml.safe_load(BUILTIN_CONFIGS[name])
        wanted = {
            end["transport"]
            for route in document["routes"]
            for end in (route["source"], route["destination"])
        }
        if all(lacking(transport) is None for transport in wanted):
            say("viewer-bridge: the built-in config's routes need %s; running -c builtin:%s, the built-in "
                "config of what is installed", needs, name)  # fmt: skip
            return f"builtin:{name}", []
    others = [name for name in _FALLBACKS if name != "foxglove"]
    raise UsageError(
        "no built-in config can run: this install has none of their extras: pip install "
        + " or ".join(f"'viewer-bridge[{TRANSPORT_EXTRAS[name]}]'" for name in absent)
        + " for the default config, or "
        + ", ".join(f"[{name}] for -c builtin:{name}" for name in others)
    )


def _with_setting(config: BridgeConfig, setting: str, config_name: str | None) -> BridgeConfig:
    """`TRANSPORT.KEY=VALUE` (the value read as YAML: 9000 is a number, true a bool) applied; a
    section of the config's own (`commands.max_age_ms=500`) is set the same way, and a plain
    top-level key of its own (`time=sim`) as `KEY=VALUE`."""
    name, equals, value = setting.partition("=")
    transport, _, key = name.partition(".")
    if equals and not key and name in _TOP_LEVEL_KEYS:
        try:
            return config.with_keys(**{name: yaml.safe_load(value)})
        except ConfigError as error:
            raise UsageError(f"--set {setting}: {error.key}: {error.reason}") from None
    if not (transport and key and equals):
        raise UsageError(
            f"--set {setting!r}: expected TRANSPORT.KEY=VALUE, e.g. foxglove.port=9000, "
            f"or KEY=VALUE for one of {', '.join(_TOP_LEVEL_KEYS)}"
        )
    if transport not in BridgeConfig.model_fields:
        _uses(config, transport, f"--set {setting}", config_name)
    try:
        return config.with_settings(transport, **{key: yaml.safe_load(value)})
    except ConfigError as error:
        raise UsageError(f"--set {setting}: {error.key}: {error.reason}") from None


# The config's own top-level keys that `--set KEY=VALUE` sets (lists and sections have options or dots).
_TOP_LEVEL_KEYS = ("time", "workers", "load_cache", "drake_lcm_types")


def _uses(config: BridgeConfig, transport: str, option: str, config_name: str | None) -> None:
    """Warn about an option for a transport that no route of the config uses: it does nothing.
    (A warning, not a refusal: one command line may serve several configs, e.g. in scripts.)"""
    used = config.transports()
    if transport not in used:
        print(
            f"viewer-bridge run: warning: {option} does nothing: no route of "
            f"{config_name or 'the built-in config'} uses the {transport} transport "
            f"(its routes use: {', '.join(used) or 'none'})",
            file=sys.stderr,
        )
