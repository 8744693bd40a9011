"""`viewer-bridge layout --out FILE.json [LOG]`: a Foxglove layout for a config's Foxglove topics
(`viewer_bridge.formats.foxglove.layout`), to import in the app (Layouts > Import from file).

The topics are the ones the config's routes from LCM to Foxglove would announce: each channel is
matched against the routes and offered, once, to a translator made as the router makes it, whose
outputs then name the topics (a camera's ports, a channel's LCM type: known only from a
message). With a log, its channels and the first message of each; without one, Drake's default
viewer channels with no message, which gives the scene and its transforms and nothing else.
"""

from __future__ import annotations

import argparse
import logging
import re
import sys
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from viewer_bridge.cli.arguments import AddCommand, input_file, lcm_types_option, output_file
from viewer_bridge.cli.play import index_log
from viewer_bridge.config.bridge import BridgeConfig, Route, destination_name
from viewer_bridge.config.options import RunOptions, config_of
from viewer_bridge.errors import BridgeError, UsageError
from viewer_bridge.shared import Shared
from viewer_bridge.translators.base import Translator
from viewer_bridge.translators.drake_stream import role_of
from viewer_bridge.translators.load_cache import LoadCache
from viewer_bridge.translators.options import FrameOptions
from viewer_bridge.translators.types import FRAME_TRANSFORMS_TYPE, RAW_IMAGE_TYPE, SCENE_UPDATE_TYPE
from viewer_bridge.transports.base import MessageType, Received
from viewer_bridge.transports.lcm_log_index import LogIndex
from viewer_bridge.util.extras import missing
from viewer_bridge.util.words import counted

if TYPE_CHECKING:
    from viewer_bridge.formats.foxglove.layout import LayoutTopics

log = logging.getLogger("viewer_bridge")

# What Drake's visualizer publishes unless told otherwise: the channels a layout with no log is for.
DRAKE_DEFAULT_CHANNELS = ("DRAKE_VIEWER_LOAD_ROBOT", "DRAKE_VIEWER_DRAW")
ILLUSTRATION = ("", "illustration")  # the roles a viewer shows at first (meldis's default)


def add_command(add: AddCommand) -> None:
    """The `layout` command's arguments, on the parser `add` makes."""
    layout = add(
        "layout",
        help="write a Foxglove layout (3D scene, camera images, a plot of LCM fields) for a config's "
        "Foxglove topics, to import in the app",
    )
    layout.add_argument(
        "log",
        nargs="?",
        type=input_file,
        help="an LCM log whose channels the layout is for (its cameras, its LCM fields); "
        "default: Drake's default viewer channels alone",
    )
    layout.add_argument(
        "--out",
        required=True,
        type=output_file((".json",)),
        metavar="FILE.json",
        help="the layout file to write",
    )
    layout.add_argument("-c", "--config", help="a YAML config (default: the built-in one)")
    lcm_types_option(layout)


@dataclass(frozen=True)
class Announced:
    """A topic a route would announce: its name, its type, the channel that made it and that
    channel's first message (None without a log)."""

    topic: str
    type: MessageType
    channel: str
    first: Received | None


def run(args: argparse.Namespace) -> int:
    """Write the layout; one line says what it holds."""
    try:
        from viewer_bridge.formats.foxglove.layout import foxglove_layout
    except ImportError as error:
        raise missing(error, "viewer-bridge layout") from None
    config = config_of(RunOptions(config=args.config, lcm_types=args.lcm_types))
    if not any(route.destination.transport == "foxglove" for route in config.routes):
        raise UsageError(
            f"no route of {args.config or 'the built-in config'} writes to Foxglove: no topic to lay out"
        )
    index = index_log(args.log, "layout") if args.log else None
    try:
        if index is not None and len(index) == 0:
            raise UsageError(f"{args.log} holds no whole LCM event: no channel to lay out")
        topics = layout_topics(config, index)
    finally:
        if index is not None:
            index.close()
    Path(args.out).write_text(foxglove_layout(topics).to_json() + "\n")
    print(
        f"viewer-bridge layout: wrote {args.out}: a 3D panel on {', '.join(topics.scenes) or 'no scene'} "
        f"in {topics.frame}, {counted(len(topics.images), 'image panel')}, a plot of "
        f"{counted(len(topics.plots), 'field')} "
        "(Foxglove: Layouts > Import from file)",
        file=sys.stderr,
    )
    return 0


def layout_topics(config: BridgeConfig, index: LogIndex | None) -> LayoutTopics:
    """What the layout shows of what the config's Foxglove routes announce for the log's channels."""
    from viewer_bridge.formats.foxglove.layout import PLOT_FIELDS, LayoutTopics, message_path
    from viewer_bridge.lcmcodec.library import TypeLibrary

    lcm_types = TypeLibrary.load(config.lcm_types, drake=config.drake_lcm_types) if index else None
    shared = Shared(lcm_types, given=[LoadCache()])  # the loads of this one look, in memory
    channels = _channels(index) if index is not None else [(name, None) for name in DRAKE_DEFAULT_CHANNELS]
    announced = list(_announced(config, shared, channels))
    scenes = [each for each in announced if each.type == SCENE_UPDATE_TYPE]
    plots = [message_path(each.topic, field) for each in announced for field in _plot_fields(shared, each)]
    return LayoutTopics(
        scenes=_names(scenes),
        hidden_scenes=frozenset(each.topic for each in scenes if role_of(each.channel) not in ILLUSTRATION),
        transforms=_names(each for each in announced if each.type == FRAME_TRANSFORMS_TYPE),
        images=_names(each for each in announced if each.type == RAW_IMAGE_TYPE),
        plots=tuple(plots[:PLOT_FIELDS]),
        frame=_world_frame(config),
    )


def _channels(index: LogIndex) -> list[tuple[str, Received | None]]:
    """Each channel of the log with its first message."""
    firsts: list[tuple[str, Received | None]] = []
    for events in index.by_channel:
        event = index.event(int(events[0]))
        firsts.append((event.channel, Received(event.channel, event.data, event.utime)))
    return firsts


def _plot_fields(shared: Shared, announced: Announced) -> list[str]:
    """A topic's fields worth a first plot: its LCM message's numbers, when the topic is that
    message's ROS 2 mapping (whose field names the decoded message has); none for any other."""
    from viewer_bridge.formats.foxglove.layout import numeric_paths

    first = announced.first
    lcm_type = None if first is None else shared.lcm_types.for_data(first.data, announced.channel)
    if first is None or lcm_type is None or lcm_type.ros_type != announced.type.name:
        return []
    try:
        return numeric_paths(lcm_type.to_dict(first.data, bytes_summary=False))
    except BridgeError as error:  # bad bytes under a known fingerprint
        log.warning("viewer-bridge layout: %s: %s: no field to plot", announced.channel, error)
        return []


def _announced(
    config: BridgeConfig, shared: Shared, channels: Sequence[tuple[str, Received | None]]
) -> Iterator[Announced]:
    """Per route from LCM to Foxglove, one translator per stream (the channels whose groups are
    the same), offered each channel's message as the router offers it; then its outputs' topics."""
    for route in config.routes:
        if route.source.transport != "lcm" or route.destination.transport != "foxglove":
            continue
        pattern = re.compile(route.source.name)
        streams: dict[tuple[str | None, ...], tuple[str, Translator, str, Received | None]] = {}
        for channel, first in channels:
            match = pattern.fullmatch(channel)
            if match is None:
                continue
            try:
                if match.groups() not in streams:
                    translator = route.translator_class()(route.translator_options(), shared=shared)
                    name = destination_name(route.destination.name, match)
                    streams[match.groups()] = (name, translator, channel, first)
                name, translator, _, _ = streams[match.groups()]
                if first is not None:
                    translator.observe(first)
            except (
                BridgeError
            ) as error:  # a message no topic comes of (an unknown type, bad bytes): said, left out
                log.warning("viewer-bridge layout: %s (route %s): %s: left out", channel, route.name, error)
        for name, translator, channel, first in streams.values():
            for output in translator.outputs:
                yield Announced(name + output.suffix, output.type, channel, first)


def _world_frame(config: BridgeConfig) -> str:
    """The frame the transforms hang from: the first Foxglove transforms route's `world_frame`."""
    for route in config.routes:
        if _writes(route, FRAME_TRANSFORMS_TYPE) and isinstance(
            options := route.translator_options(), FrameOptions
        ):
            return options.world_frame
    return FrameOptions().world_frame


def _writes(route: Route, message_type: MessageType) -> bool:
    return route.destination.transport == "foxglove" and message_type in route.translator_class().writes(
        route.translator_options()
    )


def _names(announced: Iterable[Announced]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(each.topic for each in announced))
