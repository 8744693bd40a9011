"""The router's configuration: transports, and a flat list of routes.

A route names a source (a transport and a channel or topic, matched in full as a regular
expression), a translator (`bridge.translators.TRANSLATORS`), a destination whose name is a
template over the source's regex groups (`{1}`; `{1:lower}`; `{1:path}` turns `_PROXIMITY` into
`/proximity` and `` into ``; `{1:topic}` makes any text a valid ROS name token), QoS, and a rate
policy. `DEFAULT_CONFIG` bridges Drake's default
channels to ROS 2 under `/drake`. Mistakes are `ConfigError`s with file, line and field.
"""

from __future__ import annotations

import re
import string
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from bridge.errors import ConfigError
from bridge.yamldoc import YamlDocument

Transport = Literal["lcm", "ros", "ign"]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class LcmSettings(_Strict):
    url: str = "udpm://239.255.76.67:7667?ttl=0"


class RosSettings(_Strict):
    node: str = "viewer_bridge"
    namespace: str = ""
    use_sim_time: bool = False


class IgnSettings(_Strict):
    partition: str | None = None  # default: IGN_PARTITION, or hostname:username
    ip: str | None = None  # default: IGN_IP, or 127.0.0.1


class Endpoint(_Strict):
    transport: Transport
    name: str  # a channel or topic; a regex for sources, a template for destinations


class Qos(_Strict):
    depth: int = Field(10, ge=1, le=100_000)
    reliability: Literal["reliable", "best_effort"] = "reliable"
    durability: Literal["volatile", "transient_local"] | None = None  # None: the translator's choice


class Rate(_Strict):
    policy: Literal["all", "latest"] = "latest"
    max_hz: float | None = Field(None, gt=0)


class Route(_Strict):
    name: str
    source: Endpoint
    translator: str
    destination: Endpoint
    qos: Qos = Qos()
    rate: Rate = Rate()
    options: dict[str, Any] = {}

    @field_validator("source")
    @classmethod
    def _source_is_a_regex(cls, source: Endpoint) -> Endpoint:
        try:
            re.compile(source.name)
        except re.error as error:
            raise ValueError(f"name is not a regular expression: {error}") from None
        return source

    @model_validator(mode="after")
    def _known_translator(self) -> Route:
        from bridge.translators import TRANSLATORS  # the registry imports the formats: keep config light

        translator = TRANSLATORS.get(self.translator)
        if translator is None:
            raise ValueError(
                f"unknown translator {self.translator!r} (known: {', '.join(sorted(TRANSLATORS))})"
            )
        _check_template(self.destination.name, re.compile(self.source.name).groups)
        if self.source.transport == "ign" and not re.fullmatch(r"[A-Za-z0-9_/~-]+", self.source.name):
            # ign-transport subscribes by exact topic: a pattern would wait for a topic that never exists
            raise ValueError(f"an ign source is one topic name, not a pattern: {self.source.name!r}")
        package = self.options.get("package", "ignition")
        if package not in ("ignition", "gz"):
            raise ValueError(f"options.package must be 'ignition' or 'gz', not {package!r}")
        if self.source.transport != translator.source or self.destination.transport != translator.destination:
            raise ValueError(
                f"translator {self.translator} goes from {translator.source} to {translator.destination}, "
                f"not {self.source.transport} to {self.destination.transport}"
            )
        return self


class BridgeConfig(_Strict):
    lcm: LcmSettings = LcmSettings()
    ros: RosSettings = RosSettings()
    ign: IgnSettings = IgnSettings()
    load_cache: str | None = None  # a folder where the last load per channel is kept across runs
    routes: list[Route]

    @model_validator(mode="after")
    def _unique_route_names(self) -> BridgeConfig:
        names = [route.name for route in self.routes]
        duplicates = sorted({name for name in names if names.count(name) > 1})
        if duplicates:
            raise ValueError(f"route names must be unique: {', '.join(duplicates)}")
        return self


class _Template(string.Formatter):
    """`{1}`, `{1:lower}`, `{1:path}` over a regex match's groups (a missing group is empty)."""

    def format_field(self, value: Any, format_spec: str) -> str:
        text = "" if value is None else str(value)
        if format_spec == "lower":
            return text.lower()
        if format_spec == "path":  # "_PROXIMITY" -> "/proximity"; "" stays ""
            return "/" + text.lstrip("_").lower() if text else ""
        if format_spec == "topic":  # any text as one valid ROS name token: "my client!" -> "my_client_"
            token = re.sub(r"[^A-Za-z0-9_]", "_", text)
            return token if token[:1].isalpha() else f"n{token}"
        if format_spec:
            raise ValueError(f"unknown format spec {format_spec!r}")
        return text


def _check_template(template: str, groups: int) -> None:
    """Refuse a destination template that names a group the source does not have, or a bad spec."""
    try:
        _Template().format(template, "x", *(["x"] * groups))
    except (IndexError, KeyError, ValueError) as error:
        raise ValueError(
            f"destination name {template!r} does not fit a source with {groups} groups "
            f"(use {{0}}..{{{groups}}}, with :lower, :path or :topic): {error}"
        ) from None


def destination_name(template: str, match: re.Match[str]) -> str:
    return _Template().format(template, match.group(0), *match.groups())


DEFAULT_CONFIG = """\
# viewer-bridge's built-in configuration: Drake's default viewer channels to ROS 2 under /drake.
# An unsuffixed channel (Drake's illustration default) goes to /drake/..., a role-suffixed one
# (_ILLUSTRATION, _PROXIMITY, _PERCEPTION) to /drake/<role>/...
lcm:
  url: udpm://239.255.76.67:7667?ttl=0
ros:
  node: viewer_bridge
  namespace: ""
  use_sim_time: false
routes:
  - name: markers
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"}
    translator: drake_to_marker_array
    destination: {transport: ros, name: "/drake{1:path}/markers"}
    rate: {policy: latest}
  - name: poses
    source: {transport: lcm, name: "DRAKE_VIEWER_DRAW(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"}
    translator: drake_to_pose_array
    destination: {transport: ros, name: "/drake{1:path}/poses"}
    rate: {policy: latest}
  - name: shapes
    source: {transport: lcm, name: "DRAKE_VIEWER_LOAD_ROBOT(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"}
    translator: drake_to_shapes
    destination: {transport: ros, name: "/drake{1:path}/shapes"}
    qos: {depth: 10000}
    rate: {policy: all}
  - name: deformable
    source: {transport: lcm, name: "DRAKE_VIEWER_DEFORMABLE(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"}
    translator: drake_link_to_marker_array
    destination: {transport: ros, name: "/drake{1:path}/deformable"}
    rate: {policy: latest}
  # viewer-bridge as a Director tree viewer: every client's tree to /director/<client id>/markers.
  - name: tree_viewer
    source: {transport: lcm, name: "DIRECTOR_TREE_VIEWER_REQUEST_<([^<>]*)>"}
    translator: tree_viewer_server
    destination: {transport: ros, name: "/director/{1:topic}/markers"}
    qos: {depth: 1000}
    rate: {policy: all}
    options: {mesh_roots: []}
"""


IGN_CONFIG = """\
# Drake's default viewer channels to ign-transport (ign-msgs 8 names, as Debian's ign tools use),
# and Pose_V from ign back to LCM. For newer Gazebo, set `options: {package: gz}` on a route.
lcm:
  url: udpm://239.255.76.67:7667?ttl=0
ign: {partition: null, ip: null}
routes:
  - name: model
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"}
    translator: drake_to_ign_model_v
    destination: {transport: ign, name: "/drake{1:path}/model_v"}
  - name: pose_v
    source: {transport: lcm, name: "DRAKE_VIEWER_DRAW(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"}
    translator: drake_to_ign_pose_v
    destination: {transport: ign, name: "/drake{1:path}/pose_v"}
  - name: poses_stamped
    source: {transport: lcm, name: "DRAKE_VIEWER_DRAW(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"}
    translator: drake_to_ign_poses_stamped
    destination: {transport: ign, name: "/drake{1:path}/poses_stamped"}
  - name: from_ign
    source: {transport: ign, name: /drake_in/pose_v}
    translator: ign_pose_v_to_drake_draw
    destination: {transport: lcm, name: DRAKE_VIEWER_DRAW_FROM_IGN}
    rate: {policy: all}
"""

BUILTIN_CONFIGS = {"default": DEFAULT_CONFIG, "ign": IGN_CONFIG}


def load_config(path: str | Path | None) -> BridgeConfig:
    """The config in `path` (`builtin:NAME` for a built-in one), or the built-in default.

    Raises `ConfigError` with file:line:field.
    """
    if path is None or str(path).startswith("builtin:"):
        name = "default" if path is None else str(path).removeprefix("builtin:")
        if name not in BUILTIN_CONFIGS:
            known = ", ".join(BUILTIN_CONFIGS)
            raise ConfigError(str(path), None, "", f"no built-in config {name!r} (known: {known})")
        document = YamlDocument(f"<built-in config {name}>", BUILTIN_CONFIGS[name])
    else:
        document = YamlDocument.read(path)
    if not isinstance(document.data, dict):
        raise ConfigError(document.path, 1, "", "the config must be a mapping with a 'routes' list")
    return document.validate(BridgeConfig)


__all__ = [
    "BUILTIN_CONFIGS",
    "DEFAULT_CONFIG",
    "IGN_CONFIG",
    "BridgeConfig",
    "ConfigError",
    "Route",
    "destination_name",
    "load_config",
]
