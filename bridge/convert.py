"""Offline: an LCM log through the router's translators into an MCAP file (Foxglove opens it).

Every event of the log is offered, in order, to every route whose translator reads LCM messages
and writes the chosen schema family, as the live router would:

* `ros2`: CDR messages, each topic with the `ros2msg` schema rosbags generates for its type
  (what ROS 2 tools and Foxglove read);
* `foxglove`: Foxglove's protobuf messages (SceneUpdate, FrameTransforms), written by the
  foxglove-sdk's own MCAP writer, so the 3D panel works with no ROS message definitions.

Messages carry the log's receive time.
"""

from __future__ import annotations

import itertools
import logging
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Literal, Protocol

import foxglove
from mcap.writer import Writer
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rosbags.typesys import Stores, get_typestore

from bridge.config import BridgeConfig, Route
from bridge.router import Message, RouteRunner
from bridge.translators import TRANSLATORS, LoadCache, Output, Translator
from bridge.transports.base import CDR, LCM, CallPublisher, Publisher, Received
from bridge.transports.foxglove import foxglove_channel
from bridge.transports.lcm import read_log

log = logging.getLogger("viewer_bridge")
Schema = Literal["ros2", "foxglove"]


class _Sink(Protocol):
    """Where converted messages go: a publisher per topic, stamped with `time_ns`."""

    time_ns: int
    messages: Counter[str]

    def carries(self, output: Output) -> bool: ...

    def publisher(self, topic: str, output: Output) -> Publisher: ...

    def finish(self) -> None: ...


class _Ros2Mcap:
    """An MCAP file of ROS 2 CDR messages; channels and schemas registered as topics appear."""

    def __init__(self, path: Path) -> None:
        self._file = path.open("wb")
        self._writer = Writer(self._file)
        self._writer.start(profile="ros2", library="viewer-bridge")
        self._store = get_typestore(Stores.ROS2_JAZZY)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.messages: Counter[str] = Counter()
        self.time_ns = 0

    def carries(self, output: Output) -> bool:
        return output.type.encoding == CDR

    def publisher(self, topic: str, output: Output) -> Publisher:
        typename = output.type.name
        topic = topic if topic.startswith("/") else f"/{topic}"  # as a node in the root namespace names it
        if topic not in self._channels:
            if typename not in self._schemas:
                text, _ = self._store.generate_msgdef(typename, ros_version=2)
                self._schemas[typename] = self._writer.register_schema(typename, "ros2msg", text.encode())
            self._channels[topic] = self._writer.register_channel(topic, CDR, self._schemas[typename])
        channel_id = self._channels[topic]

        def write(data: bytes) -> None:
            self.messages[topic] += 1
            self._writer.add_message(channel_id, self.time_ns, data, self.time_ns)

        return CallPublisher(write)

    def finish(self) -> None:
        self._writer.finish()  # type: ignore[no-untyped-call]
        self._file.close()


class _FoxgloveMcap:
    """An MCAP file of Foxglove protobuf messages, written by the foxglove-sdk."""

    def __init__(self, path: Path) -> None:
        self._context = foxglove.Context()
        self._writer = foxglove.open_mcap(path, allow_overwrite=True, context=self._context)
        self.messages: Counter[str] = Counter()
        self.time_ns = 0

    def carries(self, output: Output) -> bool:
        return output.type.name.startswith("foxglove.")

    def publisher(self, topic: str, output: Output) -> Publisher:
        channel = foxglove_channel(topic, output.type, self._context)

        def write(data: bytes) -> None:
            self.messages[topic] += 1
            channel.log(data, log_time=self.time_ns)

        return CallPublisher(write)

    def finish(self) -> None:
        self._writer.close()


def convert(
    log_path: str | Path,
    mcap_path: str | Path,
    config: BridgeConfig,
    progress: bool = True,
    schema: Schema = "ros2",
) -> dict[str, int]:
    """Write the outputs of `config`'s LCM routes in the `schema` family for the log into an MCAP file.

    Returns messages written per topic. Bad messages are counted per route and reported, as
    the live router does; they do not stop the conversion.
    """
    events = read_log(log_path)
    first = next(events, None)  # a file that is not an LCM log fails here, before anything is written
    sink: _Sink = _Ros2Mcap(Path(mcap_path)) if schema == "ros2" else _FoxgloveMcap(Path(mcap_path))
    routes = [route for route in config.routes if _lcm_to(sink, route)]
    loads = LoadCache()
    runners = [RouteRunner(route, _offline(route, loads), sink.publisher) for route in routes]
    total = Path(log_path).stat().st_size
    columns = (
        TextColumn("converting"),
        BarColumn(),
        TextColumn("{task.percentage:>3.0f}%"),
        TimeRemainingColumn(),
    )
    try:
        with Progress(*columns, disable=not progress, transient=True) as bar:
            task = bar.add_task("convert", total=total)
            done = 0
            for event in itertools.chain([first] if first is not None else [], events):
                sink.time_ns = event.timestamp_us * 1000
                received = Received(event.channel, event.data, event.timestamp_us)
                for runner in runners:
                    match = runner.pattern.fullmatch(event.channel)
                    if match is not None:
                        runner.handle(Message(received, match))
                done += len(event.data) + len(event.channel) + 36  # roughly one event record
                bar.update(task, completed=min(done, total))
    finally:
        sink.finish()
    for runner in runners:
        errors = dict(runner.stats.errors)
        if errors:
            log.warning("route %s: %s", runner.route.name, errors)
    return dict(sink.messages)


def _lcm_to(sink: _Sink, route: Route) -> bool:
    """Whether a route reads LCM and writes only what the sink carries."""
    translator = TRANSLATORS.get(route.translator)
    return all(read.encoding == LCM for read in translator.reads) and all(
        sink.carries(output) for output in translator.outputs
    )


def _offline(route: Route, loads: LoadCache) -> Callable[[], Translator]:
    def make() -> Translator:
        translator = TRANSLATORS.get(route.translator)(route.translator_options(), loads)
        translator.reply = lambda channel, data: None  # offline: there is nobody to answer
        return translator

    return make
