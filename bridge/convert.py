"""Offline: an LCM log through the router's translators into an MCAP file (Foxglove opens it).

Every event of the log is offered, in order, to every route whose translator reads LCM messages
and writes the chosen schema family, as the live router would:

* `ros2`: CDR messages, each topic with the `ros2msg` schema rosbags generates for its type
  (what ROS 2 tools and Foxglove read);
* `foxglove`: Foxglove's protobuf messages (SceneUpdate, FrameTransforms), written by the
  foxglove-sdk's own MCAP writer, so the 3D panel works with no ROS message definitions.

Messages carry the log's receive time. Nothing is lost: the output is never the input, an
existing file is replaced only when asked (`force`), and the MCAP is written as `OUT.partial`,
renamed to `OUT` once complete. Stopped midway (`stop` set, e.g. by Ctrl-C), the MCAP is closed
properly (readable, with what was written so far) and left as `OUT.partial`: `Interrupted` says
how many messages it holds.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Literal, Protocol

import foxglove
from mcap.writer import Writer
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rosbags.typesys import Stores, get_typestore

from bridge.config import BridgeConfig, Route
from bridge.errors import ConvertError, Interrupted
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

    def publisher(self, topic: str, output: Output) -> Publisher:
        channel = foxglove_channel(topic, output.type, self._context)

        def write(data: bytes) -> None:
            self.messages[topic] += 1
            channel.log(data, log_time=self.time_ns)

        return CallPublisher(write)

    def finish(self) -> None:
        self._writer.close()


# What each schema family's file carries: ROS 2 CDR messages, or Foxglove's protobuf ones.
_CARRIES: dict[Schema, Callable[[Output], bool]] = {
    "ros2": lambda output: output.type.encoding == CDR,
    "foxglove": lambda output: output.type.name.startswith("foxglove."),
}


def convert(
    log_path: str | Path,
    mcap_path: str | Path,
    config: BridgeConfig,
    progress: bool = True,
    schema: Schema = "ros2",
    force: bool = False,
    config_name: str = "the config",
    stop: threading.Event | None = None,
) -> dict[str, int]:
    """Write the outputs of `config`'s LCM routes in the `schema` family for the log into an MCAP file.

    Returns messages written per topic. Bad messages are counted per route and reported, as
    the live router does; they do not stop the conversion. Raises `ConvertError` before
    anything is written when `mcap_path` is the log itself, exists (unless `force`), or no route
    writes `schema`; `Interrupted` when `stop` is set midway.
    """
    target = Path(mcap_path)
    _check_target(Path(log_path), target, force)
    events = read_log(log_path)
    first = next(events, None)  # a file that is not an LCM log fails here, before anything is written
    writes = [route for route in config.routes if _lcm_to(_CARRIES[schema], route)]
    if not writes:
        raise ConvertError(f"no route of {config_name} reads LCM and writes the {schema} schema")
    partial = target.with_name(target.name + ".partial")
    sink: _Sink = _Ros2Mcap(partial) if schema == "ros2" else _FoxgloveMcap(partial)
    loads = LoadCache()
    runners = [RouteRunner(route, _offline(route, loads), sink.publisher) for route in writes]
    stop = stop or threading.Event()
    try:
        with _progress_bar(Path(log_path).stat().st_size, progress) as advance:
            for event in itertools.chain([first] if first is not None else [], events):
                if stop.is_set():
                    break
                sink.time_ns = event.timestamp_us * 1000
                received = Received(event.channel, event.data, event.timestamp_us)
                for runner in runners:
                    match = runner.pattern.fullmatch(event.channel)
                    if match is not None:
                        runner.handle(Message(received, match))
                advance(len(event.data) + len(event.channel) + 36)  # roughly one event record
    except BaseException:
        sink.finish()
        partial.unlink(missing_ok=True)  # a failure midway leaves no file that looks like output
        raise
    sink.finish()
    _report_errors(runners)
    if stop.is_set():
        raise Interrupted(sum(sink.messages.values()), partial)
    os.replace(partial, target)
    return dict(sink.messages)


def _check_target(log_path: Path, target: Path, force: bool) -> None:
    """Refuse an output that is the input (also through a link) or, without `force`, any existing file."""
    if not target.exists():
        return
    if log_path.exists() and os.path.samefile(log_path, target):
        raise ConvertError(f"{target} is the input log {log_path}: give another output file")
    if target.is_dir():
        raise ConvertError(f"{target} is a folder, not a file")
    if not force:
        raise ConvertError(f"{target} exists: give another output file, or --force to replace it")


@contextlib.contextmanager
def _progress_bar(total: int, shown: bool) -> Iterator[Callable[[int], None]]:
    """A progress bar over `total` bytes (when `shown`); yields the function that advances it."""
    columns = (
        TextColumn("converting"),
        BarColumn(),
        TextColumn("{task.percentage:>3.0f}%"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, disable=not shown, transient=True) as bar:
        task = bar.add_task("convert", total=total)
        done = 0

        def advance(size: int) -> None:
            nonlocal done
            done += size
            bar.update(task, completed=min(done, total))

        yield advance


def _report_errors(runners: list[RouteRunner]) -> None:
    """Per route, its errors and warnings (each was logged as it happened, the first few in full)."""
    for runner in runners:
        counts = runner.stats.errors + runner.stats.warnings
        if counts:
            log.warning("route %s: %s", runner.route.name, dict(counts))


def _lcm_to(carries: Callable[[Output], bool], route: Route) -> bool:
    """Whether a route reads LCM and writes only what a sink `carries`."""
    translator = TRANSLATORS.get(route.translator)
    return all(read.encoding == LCM for read in translator.reads) and all(
        carries(output) for output in translator.outputs
    )


def _offline(route: Route, loads: LoadCache) -> Callable[[], Translator]:
    def make() -> Translator:
        translator = TRANSLATORS.get(route.translator)(route.translator_options(), loads)
        translator.reply = lambda channel, data: None  # offline: there is nobody to answer
        return translator

    return make
