"""The router's configuration: transport settings, and a flat list of routes.

A route names a source (a transport and a channel or topic, matched in full as a regular
expression), a translator (`viewer_bridge.translators.registry.TRANSLATORS`), a destination whose name is a
template over the source's regex groups (`{1}`; `{1:lower}`; `{1:path}` turns `_PROXIMITY` into
`/proximity` and `` into ``; `{1:topic}` makes any text a valid ROS name token; `{1:lcm}` a ROS 2
topic its LCM channel), QoS, a rate
policy, `lazy`, and the translator's options. Each transport's settings are the top-level
section named after it (`lcm:`, `ros:`, `ign:`, or a plugin's name), checked by its own model.
`lcm_types:` names the LCM types the routes know besides the project's and Drake's (`.lcm` files,
folders, lcm-gen'd modules; loaded once per router, `viewer_bridge.lcmcodec.library`).
`ros_topics:` (and `--ros-topics`) names ROS 2 topics to carry onto LCM, each a regex matched in
full: it makes one route per ROS graph transport the config uses (`ros_topics_<transport>`, `ros`
when it uses none), source `(REGEX)`, translator `ros_topic_to_lcm`, destination LCM `{1:lcm}`
(the topic without its leading `/`). Empty by default: nothing is carried unless named.
`time:` is the bridge's one clock, what every output is stamped with (`/tf`, poses, images,
Foxglove's messages and log times, an MCAP file's log times): `receive` (the default) or `sim`
(Drake's sim time). With `sim`, the config also publishes Drake's sim time on `/clock`: a route
`clock_<transport>` per ROS graph transport it uses (`clock_routes`), unless a route of its own
already translates `drake_to_clock`.
The built-in configs (`-c builtin:NAME`; `default` bridges Drake's default channels to ROS 2
under `/drake`) are the YAML files in `configs/`, shipped with the package and read like a user's.

Everything is checked when the config loads: the names of transports and translators, each
translator's options, and whether each route's transports carry the message types its
translator reads and writes. Mistakes are `ConfigError`s with file, line and key.
"""

from __future__ import annotations

import difflib
import re
import string
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from viewer_bridge.errors import ConfigError, InvalidName, InvalidSetting, UnknownName
from viewer_bridge.lcmcodec.from_ros import lcm_channel
from viewer_bridge.shared import TimeSource
from viewer_bridge.translators.base import Translator, TranslatorOptions
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import MessageType, Transport, TransportSettings
from viewer_bridge.transports.command_policy import CommandPolicy, checked, topic_pattern_problem
from viewer_bridge.transports.registry import TRANSPORTS
from viewer_bridge.transports.ros_names import ChannelNames, name_token
from viewer_bridge.util.resources import data_dir
from viewer_bridge.util.yamldoc import KeyPath, YamlDocument


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Endpoint(_Strict):
    transport: str  # a name in TRANSPORTS
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
    lazy: bool = False  # translate only while the destination has a subscriber (where the transport can tell)
    # A message older than this when it would be sent is dropped (`stale`); a route that writes
    # commands has the config's `commands.max_age_ms` unless it says otherwise.
    max_age_ms: float | None = Field(None, gt=0)
    # At most this many streams (sets of captured groups: LCM channels, topics) get a translator
    # and publishers of their own; a message of one more is held (`too_many_streams`), so a bus
    # with 10,000 channel names cannot make 10,000 publishers.
    max_streams: int = Field(1000, ge=1)
    # A stream quiet this long gives its translator and publishers back when the route has
    # `max_streams` and a new one comes: a flood of names that stops cannot hold the lanes for good.
    stream_idle_s: float = Field(30.0, gt=0)
    # The worker process this route runs on when the bridge runs several (`workers`); None: placed
    # by its source (`viewer_bridge.router.workers.place`).
    worker: int | None = Field(None, ge=0)
    options: dict[str, Any] = {}
    _options: TranslatorOptions | None = PrivateAttr(None)

    @field_validator("source")
    @classmethod
    def _source_is_a_regex(cls, source: Endpoint) -> Endpoint:
        try:
            re.compile(source.name)
        except re.error as error:
            raise InvalidSetting(f"name is not a regular expression: {error}") from None
        return source

    @model_validator(mode="after")
    def _destination_fits_source(self) -> Route:
        _check_template(self.destination.name, re.compile(self.source.name).groups)
        return self

    def translator_class(self) -> type[Translator]:
        return TRANSLATORS.get(self.translator)

    def translator_options(self) -> TranslatorOptions:
        """The options as the translator's model (checked when the config loaded)."""
        if self._options is None:
            self._options = self.translator_class().Options.model_validate(self.options)
        return self._options


class BridgeConfig(BaseModel):
    """The whole config; every top-level key besides these is a transport's settings section."""

    model_config = ConfigDict(extra="allow")
    load_cache: str | None = None  # a folder where the last load per channel is kept across runs
    # LCM types the routes know besides the project's own: .lcm files, folders of them (searched
    # recursively) and lcm-gen'd Python modules by import name (`--lcm-types` adds to these).
    lcm_types: list[str] = []
    # also Drake's own types (pydrake's `drake` module), when pydrake is installed
    drake_lcm_types: bool = True
    # The LCM channels the way back (ros_to_lcm) may write, and how fresh a command must be.
    commands: CommandPolicy = CommandPolicy()
    # ROS 2 topics to carry onto LCM (`--ros-topics` adds to these): regexes, each matched in full.
    ros_topics: list[str] = []
    # Processes the routes run on (`--workers`); 1: the routes run in the bridge's own process.
    workers: int = Field(1, ge=1, le=256)
    # The clock of every stamp and log time: each message's receive time (what RViz and tf2 take
    # out of the box), or Drake's sim time (`sim`: also /clock, for use_sim_time nodes).
    time: TimeSource = "receive"
    routes: list[Route]
    _settings: dict[str, TransportSettings] = PrivateAttr(default_factory=dict)
    _own_routes: list[Route] = PrivateAttr(
        default_factory=list
    )  # the routes but those ros_topics and time made

    @field_validator("ros_topics")
    @classmethod
    def _regular_expressions(cls, patterns: list[str]) -> list[str]:
        return checked(patterns, topic_pattern_problem)

    @model_validator(mode="after")
    def _check(self, info: ValidationInfo) -> BridgeConfig:
        document = (info.context or {}).get("document")
        check = _Checker(document if isinstance(document, YamlDocument) else None)
        for name, section in (self.model_extra or {}).items():
            known = (
                "a config key (load_cache, lcm_types, drake_lcm_types, commands, ros_topics, workers, time, routes) "
                "nor a transport"
            )
            transport = check.transport(name, (name,), known)
            self._settings[name] = check.model(transport.Settings, section or {}, (name,))
        names = [route.name for route in self.routes]
        for index, route in enumerate(self.routes):
            check.route(route, ("routes", index))
            if route.name in names[:index]:
                raise check.error(
                    ("routes", index, "name"), f"route names must be unique: {route.name!r} again"
                )
        topic_routes = ros_topic_routes(self.ros_topics, self.routes)
        made = [
            *((route, "ros_topics") for route in topic_routes),
            *((route, "time") for route in clock_routes(self.time, [*self.routes, *topic_routes])),
        ]
        for route, key in made:
            check.route(route, (key,))
            if route.name in names:
                at = ("routes", names.index(route.name), "name")
                raise check.error(at, f"{route.name!r} is the name of the route {key} makes: rename this one")
        self._own_routes = list(self.routes)
        self.routes = [*self.routes, *(route for route, _ in made)]
        for name in self.transports():  # a used transport without a section: is a setting required?
            if name not in self._settings:
                self._settings[name] = check.model(TRANSPORTS.get(name).Settings, {}, (name,))
        return self

    def transports(self) -> list[str]:
        """The transports the routes use, in order of first use."""
        used = [
            name for route in self.routes for name in (route.source.transport, route.destination.transport)
        ]
        return list(dict.fromkeys(used))

    def settings(self, transport: str) -> TransportSettings:
        """A transport's settings: its section, else its defaults."""
        if transport not in self._settings:
            self._settings[transport] = TRANSPORTS.get(transport).Settings()
        return self._settings[transport]

    def allowing_commands(self, patterns: list[str]) -> BridgeConfig:
        """The same config with more LCM channels the way back may write (`--allow-commands`)."""
        return self.model_copy(update={"commands": self.commands.widened(patterns)}) if patterns else self

    def with_lcm_types(self, sources: list[str]) -> BridgeConfig:
        """The same config with more LCM types to know (`--lcm-types`) after its `lcm_types`."""
        return self.model_copy(update={"lcm_types": [*self.lcm_types, *sources]}) if sources else self

    def with_ros_topics(self, patterns: list[str]) -> BridgeConfig:
        """The same config carrying more ROS 2 topics onto LCM (`--ros-topics`) after its `ros_topics`."""
        return self._checked_again({"ros_topics": [*self.ros_topics, *patterns]}) if patterns else self

    def with_settings(self, transport: str, **values: Any) -> BridgeConfig:
        """The same config with some of a transport's settings replaced (e.g. a command line's --lcm-url)."""
        current = self.model_dump().get(transport) or {}
        return self._checked_again({transport: {**current, **values}})

    def with_keys(self, **values: Any) -> BridgeConfig:
        """The same config with some of its own top-level keys replaced (a command line's `--set time=sim`)."""
        return self._checked_again(values)

    def _checked_again(self, changes: dict[str, Any]) -> BridgeConfig:
        """This config with `changes` to its top-level keys, checked again (a bad value is a
        ConfigError); made from its own routes, so that `ros_topics` makes its routes anew."""
        # Each route as its config wrote it: a QoS policy it left unset follows the publishers.
        routes = [route.model_dump(exclude_unset=True) for route in self._own_routes]
        data = {**self.model_dump(), "routes": routes, **changes}
        try:
            return BridgeConfig.model_validate(data)
        except ValidationError as error:  # a section of the config's own (a transport's raises ConfigError)
            raise YamlDocument("<config>", "").validation_error(error, model=BridgeConfig) from None


class _Checker:
    """The config's semantic checks; errors name the file, line and key when there is a file."""

    def __init__(self, document: YamlDocument | None) -> None:
        self.document = document or YamlDocument("<config>", "")  # no file: no lines to name

    def error(self, key_path: KeyPath, reason: str) -> ConfigError:
        return self.document.error(key_path, reason)

    def model(self, model: type[Any], data: Any, at: KeyPath) -> Any:
        try:
            return model.model_validate(data)
        except ValidationError as error:
            raise self.document.validation_error(error, at, model) from None

    def transport(self, name: str, at: KeyPath, what: str = "a transport") -> type[Transport]:
        try:
            return TRANSPORTS.get(name)
        except UnknownName as error:
            known = ", ".join(error.known)
            raise self.error(at, f"{name!r} is not {what} (transports: {known})") from None

    def route(self, route: Route, at: KeyPath) -> None:
        try:
            translator = TRANSLATORS.get(route.translator)
        except UnknownName as error:
            raise self.error((*at, "translator"), str(error)) from None
        route._options = self.model(translator.Options, route.options, (*at, "options"))
        source = self.transport(route.source.transport, (*at, "source", "transport"))
        destination = self.transport(route.destination.transport, (*at, "destination", "transport"))
        try:
            source.check_source(route.source.name)
        except InvalidName as error:
            raise self.error((*at, "source", "name"), str(error)) from None
        try:
            destination.check_destination(_sample_destination(route))
        except InvalidName as error:
            raise self.error((*at, "destination", "name"), str(error)) from None
        self._carried(
            source, route.source.transport, translator.reads, (*at, "source", "transport"), route, "reads"
        )
        self._carried(
            destination,
            route.destination.transport,
            translator.writes(route._options),
            (*at, "destination", "transport"),
            route,
            "writes",
        )
        if translator.replies is not None:
            self._carried(
                source,
                route.source.transport,
                (translator.replies,),
                (*at, "source", "transport"),
                route,
                "answers with",
            )

    def _carried(
        self,
        transport: type[Transport],
        name: str,
        types: tuple[MessageType, ...],
        at: KeyPath,
        route: Route,
        verb: str,
    ) -> None:
        refused = [str(message_type) for message_type in types if not transport.carries(message_type)]
        if refused:
            raise self.error(
                at,
                f"translator {route.translator} {verb} {', '.join(refused)}, which the {name} transport does not carry",
            )


class _Template(string.Formatter):
    """`{1}`, `{1:lower}`, `{1:path}`, `{1:topic}`, `{1:channel}` over a regex match's groups (a
    missing group is empty); `names` remembers the channels `:topic` made tokens of, for `:channel`;
    `commands`, on a route that writes commands, is the only table `:channel` reads (`CommandPolicy.channel`)."""

    def __init__(self, names: ChannelNames | None = None, commands: CommandPolicy | None = None) -> None:
        super().__init__()
        self._names = names
        self._commands = commands

    def get_field(self, field_name: str, args: Sequence[Any], kwargs: Mapping[str, Any]) -> Any:
        # Only group numbers: `{1.path}` or `{1[a]}` would reach into the group's str (found by
        # bench/fuzz.py as an AttributeError escaping the config check).
        if not field_name.isdigit():
            raise InvalidName(f"{{{field_name}}} is not a group number")
        return super().get_field(field_name, args, kwargs)

    def format_field(self, value: Any, format_spec: str) -> str:
        text = "" if value is None else str(value)
        if format_spec == "lower":
            return text.lower()
        if format_spec == "path":  # "_PROXIMITY" -> "/proximity"; "" stays ""
            return "/" + text.lstrip("_").lower() if text else ""
        if format_spec == "topic":  # any text as one valid ROS name token: "my client!" -> "my_client_"
            return name_token(text) if self._names is None else self._names.token(text)
        if format_spec == "channel":  # a token back to the LCM channel it was made of: "A_B" -> "A.B"
            if self._commands is not None:  # a command: only the allow-list says which channel
                return self._commands.channel(text)
            return text if self._names is None else self._names.channel(text)
        if format_spec == "lcm":  # a ROS 2 topic as the LCM channel it is carried on: "/a/b" -> "a/b"
            return lcm_channel(text)
        if format_spec:
            raise InvalidName(f"unknown format spec {format_spec!r}")
        return text


def _check_template(template: str, groups: int) -> None:
    """Refuse a destination template that names a group the source does not have, or a bad spec."""
    try:
        _Template().format(template, "x", *(["x"] * groups))
    except (IndexError, KeyError, ValueError) as error:
        raise InvalidName(
            f"destination name {template!r} does not fit a source with {groups} groups "
            f"(use {{0}}..{{{groups}}}, with :lower, :path, :topic, :channel or :lcm): {error}"
        ) from None


def _sample_destination(route: Route) -> str:
    """The route's destination name for a sample message (each group of its source: `x`)."""
    groups = re.compile(route.source.name).groups
    return _Template().format(route.destination.name, "x", *(["x"] * groups))


def destination_name(
    template: str,
    match: re.Match[str],
    names: ChannelNames | None = None,
    commands: CommandPolicy | None = None,
) -> str:
    """The destination name for a message whose source name `match`ed (`names`, `commands`: see
    `_Template`). Raises `Held` for a `:channel` that cannot be told."""
    return _Template(names, commands).format(template, match.group(0), *match.groups())


ROS_TOPICS_TRANSLATOR = "ros_topic_to_lcm"
ROS_TOPIC_CHANNEL = "{1:lcm}"  # docs/PROTOCOLS.md section 14: /joint_states -> joint_states


def ros_topic_routes(patterns: Sequence[str], routes: Sequence[Route]) -> list[Route]:
    """The routes `ros_topics` makes: the topics any of `patterns` matches in full, onto LCM, from
    each ROS graph transport `routes` use (DDS, rmw_zenoh), else from `ros`; none without patterns."""
    if not patterns:
        return []
    used = dict.fromkeys(
        name for route in routes for name in (route.source.transport, route.destination.transport)
    )
    graphs = [name for name in used if TRANSPORTS.get(name).ros_graph] or ["ros"]
    alternatives = patterns[0] if len(patterns) == 1 else "|".join(f"(?:{pattern})" for pattern in patterns)
    # The whole topic is group 1: a stream (a lane, and its channel) per topic, whatever groups the patterns have.
    source = f"({alternatives})"
    return [
        Route(
            name=f"ros_topics_{transport}",
            source=Endpoint(transport=transport, name=source),
            translator=ROS_TOPICS_TRANSLATOR,
            destination=Endpoint(transport="lcm", name=ROS_TOPIC_CHANNEL),
            qos=Qos(depth=100),
            rate=Rate(policy="all"),  # every message: a topic's samples, as a log of it would hold
        )
        for transport in graphs
    ]


CLOCK_TRANSLATOR = "drake_to_clock"
CLOCK_SOURCE = "DRAKE_VIEWER_DRAW(_ILLUSTRATION|_PROXIMITY|_PERCEPTION)?"  # Drake's draws, every role


def clock_routes(time: TimeSource, routes: Sequence[Route]) -> list[Route]:
    """The routes `time: sim` makes: Drake's draws' sim time on `/clock` (rosgraph_msgs/Clock), from
    each ROS graph transport `routes` use; none with `time: receive`, none when a route of the
    config translates `drake_to_clock` already, none when the config has no ROS graph."""
    if time != "sim" or any(route.translator == CLOCK_TRANSLATOR for route in routes):
        return []
    used = dict.fromkeys(
        name for route in routes for name in (route.source.transport, route.destination.transport)
    )
    return [
        Route(
            name=f"clock_{transport}",
            source=Endpoint(transport="lcm", name=CLOCK_SOURCE),
            translator=CLOCK_TRANSLATOR,
            destination=Endpoint(transport=transport, name="/clock"),
            rate=Rate(policy="latest"),  # a time behind the newest is of no use to anyone
        )
        for transport in used
        if TRANSPORTS.get(transport).ros_graph
    ]


def _builtin_configs() -> dict[str, str]:
    """The configs shipped in `configs/` (`builtin:NAME`), by name, the default first."""
    paths = sorted(data_dir("configs").glob("*.yaml"), key=lambda path: (path.stem != "default", path.stem))
    return {path.stem: path.read_text() for path in paths}


BUILTIN_CONFIGS = _builtin_configs()
DEFAULT_CONFIG = BUILTIN_CONFIGS["default"]


def load_config(path: str | Path | None, *, without: Sequence[str] = ()) -> BridgeConfig:
    """The config in `path` (`builtin:NAME` for a built-in one), or the built-in default;
    `without` transports, the config less its routes on those transports and their sections.

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
    _check_top_level_keys(document)
    if without:
        data = {key: value for key, value in document.data.items() if key not in without}
        data["routes"] = [
            route for route in data.get("routes") or [] if not any(routes_on(route, name) for name in without)
        ]
        document.data = data
    return document.validate(BridgeConfig, context={"document": document})


def _check_top_level_keys(document: YamlDocument) -> None:
    """A top-level key that is a misspelling of a config key or a transport (`rouets:`) is named,
    with the key it means, before the check of the rest (which would say `routes: Field required`)."""
    keys = list(BridgeConfig.model_fields)
    transports = TRANSPORTS.names()
    for key in document.data:
        if isinstance(key, str) and key not in keys and key not in transports:
            close = difflib.get_close_matches(key, [*keys, *transports], n=1)
            if close:
                raise document.error(
                    (key,),
                    f"unknown key {key!r} (did you mean {close[0]!r}?); known keys: {', '.join(keys)}, "
                    f"and a transport's section ({', '.join(transports)})",
                )


def routes_on(route: Any, transport: str) -> bool:
    """Whether a route, as a config's YAML has it, reads or writes `transport`."""
    ends = [route.get(end) for end in ("source", "destination")] if isinstance(route, dict) else []
    return any(isinstance(end, dict) and end.get("transport") == transport for end in ends)
