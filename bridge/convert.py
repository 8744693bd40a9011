"""Offline: an LCM log through the router's translators into a ROS 2 MCAP file (Foxglove opens it).

Every event of the log is offered, in order, to every route whose translator reads LCM messages
and writes CDR (ROS 2) ones, as the live router would; each output is written as a CDR message
on its topic, with the `ros2msg` schema rosbags generates for its type and the log's receive time.
"""

from __future__ import annotations

import logging
from collections import Counter
from collections.abc import Callable
from pathlib import Path

from mcap.writer import Writer
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rosbags.typesys import Stores, get_typestore

from bridge.config import BridgeConfig, Route
from bridge.router import Message, RouteRunner
from bridge.translators import TRANSLATORS, LoadCache, Output, Translator
from bridge.transports.base import CDR, LCM, CallPublisher, Publisher, Received
from bridge.transports.lcm import read_log

log = logging.getLogger("viewer_bridge")
_STORE = get_typestore(Stores.ROS2_JAZZY)


class _McapTopics:
    """Channels and schemas of an MCAP file, registered as topics first appear."""

    def __init__(self, writer: Writer) -> None:
        self._writer = writer
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.messages: Counter[str] = Counter()

    def publisher(self, topic: str, output: Output) -> Publisher:
        typename = output.type.name
        if topic not in self._channels:
            if typename not in self._schemas:
                text, _ = _STORE.generate_msgdef(typename, ros_version=2)
                self._schemas[typename] = self._writer.register_schema(typename, "ros2msg", text.encode())
            self._channels[topic] = self._writer.register_channel(topic, CDR, self._schemas[typename])
        channel_id = self._channels[topic]

        def write(data: bytes) -> None:
            self.messages[topic] += 1
            self._writer.add_message(channel_id, self.time_ns, data, self.time_ns)

        return CallPublisher(write)

    time_ns = 0


def _lcm_to_cdr(route: Route) -> bool:
    translator = TRANSLATORS.get(route.translator)
    return all(read.encoding == LCM for read in translator.reads) and all(
        output.type.encoding == CDR for output in translator.outputs
    )


def convert(
    log_path: str | Path, mcap_path: str | Path, config: BridgeConfig, progress: bool = True
) -> dict[str, int]:
    """Write the ROS 2 outputs of `config`'s routes for the log into an MCAP file.

    Returns messages written per topic. Bad messages are counted per route and reported, as
    the live router does; they do not stop the conversion.
    """
    routes = [route for route in config.routes if _lcm_to_cdr(route)]
    loads = LoadCache()
    total = Path(log_path).stat().st_size
    with open(mcap_path, "wb") as file:
        writer = Writer(file)
        writer.start(profile="ros2", library="viewer-bridge")
        topics = _McapTopics(writer)
        runners = []
        for route in routes:
            runners.append(RouteRunner(route, _offline(route, loads), topics.publisher))
        columns = (
            TextColumn("converting"),
            BarColumn(),
            TextColumn("{task.percentage:>3.0f}%"),
            TimeRemainingColumn(),
        )
        with Progress(*columns, disable=not progress, transient=True) as bar:
            task = bar.add_task("convert", total=total)
            done = 0
            for event in read_log(log_path):
                topics.time_ns = event.timestamp_us * 1000
                received = Received(event.channel, event.data, event.timestamp_us)
                for runner in runners:
                    match = runner.pattern.fullmatch(event.channel)
                    if match is not None:
                        runner.handle(Message(received, match))
                done += len(event.data) + len(event.channel) + 36  # roughly one event record
                bar.update(task, completed=min(done, total))
        writer.finish()  # type: ignore[no-untyped-call]
    for runner in runners:
        errors = dict(runner.stats.errors)
        if errors:
            log.warning("route %s: %s", runner.route.name, errors)
    return dict(topics.messages)


def _offline(route: Route, loads: LoadCache) -> Callable[[], Translator]:
    def make() -> Translator:
        translator = TRANSLATORS.get(route.translator)(route.translator_options(), loads)
        translator.reply = lambda channel, data: None  # offline: there is nobody to answer
        return translator

    return make
