"""Offline: an LCM log through the router's translators into an MCAP file (Foxglove opens it), or
into a Rerun `.rrd` file (the output's extension says which, or `output_format`'s `chosen`).

The config's routes whose translator reads LCM messages and writes the chosen schema family
become a router whose every route ends in the `mcap` transport (viewer_bridge/transports/mcap.py), and
every event of the log is fed to it in order (`Router.feed`), as the live router would take it:

* `ros2`: CDR messages, each topic with the `ros2msg` schema rosbags generates for its type
  (what ROS 2 tools and Foxglove read);
* `foxglove`: Foxglove's protobuf messages (SceneUpdate, FrameTransforms), written by the
  foxglove-sdk's own MCAP writer, so the 3D panel works with no ROS message definitions.

An output named `*.rrd` is a Rerun recording instead, written by the `rerun` transport
(viewer_bridge/transports/rerun.py) from the routes that write Rerun chunks; `schema` is then
not used. Messages carry the log's receive time. Nothing is lost: the output is never the input, an
existing file is replaced only when asked (`force`), and the MCAP is written as `OUT.partial`,
renamed to `OUT` once complete. Stopped midway (`stop` set, e.g. by Ctrl-C), the MCAP is closed
properly (readable, with what was written so far) and left as `OUT.partial`: `Interrupted` says
how many messages it holds (none: the file is removed, and it says nothing is kept).

What a conversion wrote comes back as a `Conversion`: its counts, and the channels it skipped
and why, for the command line to say in one line each (`summary`, `skipped_lines`).
"""

from __future__ import annotations

import contextlib
import itertools
import json
import logging
import os
import re
import threading
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from viewer_bridge.config.bridge import BridgeConfig, Endpoint, Route
from viewer_bridge.errors import ConvertError, Interrupted
from viewer_bridge.router.router import Router
from viewer_bridge.router.status import LEGEND, Snapshot
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import LCM, MessageType, Received
from viewer_bridge.transports.lcm import read_log
from viewer_bridge.transports.registry import TRANSPORTS
from viewer_bridge.util.partial import partial_output
from viewer_bridge.util.progress import progress as progress_of
from viewer_bridge.util.words import counted

if TYPE_CHECKING:
    from viewer_bridge.transports.mcap import Profile

log = logging.getLogger("viewer_bridge")

Format = Literal["mcap", "rrd"]
FORMATS: dict[str, Format] = {".mcap": "mcap", ".rrd": "rrd"}  # by the output's extension


@dataclass(frozen=True, slots=True)
class Conversion:
    """What a conversion wrote into `path` and what it skipped.

    `messages`: per topic (MCAP) or per destination (Rerun); `chunks`: per entity path (Rerun);
    `skipped`: messages held back, by (channel, kind); `channels`: the log's; `lcm_channels`: the
    regex that narrowed the routes of any LCM type, if one did."""

    path: Path
    format: Format
    messages: dict[str, int]
    chunks: dict[str, int]
    skipped: dict[tuple[str, str], int]
    channels: tuple[str, ...]
    lcm_channels: str | None = None

    @property
    def written(self) -> int:
        return sum(self.messages.values())

    def problem(self) -> str | None:
        """Why the conversion did not do what was asked (one line), or None: `lcm_channels`
        matched no channel of the log, or nothing was written."""
        its = f"(its channels: {_listed(self.channels)})"
        if self.lcm_channels is not None and not any(
            re.fullmatch(self.lcm_channels, c) for c in self.channels
        ):
            return f"--lcm-channels {self.lcm_channels!r} matches no channel of the log {its}"
        if self.written:
            return None
        if self.skipped:
            return f"nothing written to {self.path}: every message read was skipped (said above)"
        return f"nothing written to {self.path}: no route reads a channel of the log {its}"

    def summary(self) -> str:
        """`wrote OUT: 120 messages on 6 topics` (an .rrd: its chunks and entities)."""
        if self.format == "rrd":
            counts = f"{counted(sum(self.chunks.values()), 'chunk')}, {counted(len(self.chunks), 'entity', 'entities')}"
        else:
            counts = f"{counted(self.written, 'message')} on {counted(len(self.messages), 'topic')}"
        return f"wrote {self.path}: {counts}"

    def skipped_lines(self) -> list[str]:
        """One line per channel and reason, in the live legend's words:
        `skipped: 10 messages on LAB_STATUS: unknown_type, no known LCM type (--lcm-types ...)`."""
        return [
            f"skipped: {counted(count, 'message')} on {channel}: {kind}"
            + (f", {LEGEND[kind]}" if kind in LEGEND else "")
            for (channel, kind), count in sorted(self.skipped.items())
        ]


def _listed(names: tuple[str, ...], most: int = 8) -> str:
    """Names for a line: the first `most`, and how many more."""
    more = f" and {len(names) - most} more" if len(names) > most else ""
    return (", ".join(names[:most]) or "none") + more


def output_format(path: str | Path, chosen: Format | None = None) -> Format:
    """What to write: `chosen`, else what the output's extension says; `ConvertError` for another."""
    if chosen is not None:
        return chosen
    found = FORMATS.get(Path(path).suffix.lower())
    if found is None:
        raise ConvertError(
            f"{path}: convert writes .mcap (MCAP) or .rrd (Rerun) files: "
            "name the output so, or say which with --format mcap|rrd"
        )
    return found


def convert(
    log_path: str | Path,
    mcap_path: str | Path,
    config: BridgeConfig,
    progress: bool = True,
    schema: Profile = "ros2",
    force: bool = False,
    config_name: str = "the config",
    stop: threading.Event | None = None,
    lcm_channels: str | None = None,
    output: Format | None = None,
) -> Conversion:
    """Write the outputs of `config`'s LCM routes in the `schema` family for the log into an MCAP file
    (or, for an `.rrd` output, the routes that write Rerun chunks into a Rerun recording).

    Returns what was written (`Conversion`); a conversion that wrote nothing leaves no file. Bad
    messages are counted per route and reported, as the live router does; they do not stop the
    conversion. Raises `ConvertError` before anything is written when `mcap_path` is the log
    itself, exists (unless `force`), has an extension of no format (unless `output` names one), or
    no route writes `schema`; `Interrupted` when `stop` is set midway. `lcm_channels`, a regex,
    narrows the routes of any LCM type (`lcm_to_ros`: `/lcm/<channel>`) to the channels it fully
    matches.
    """
    target = Path(mcap_path)
    chosen = checked_output(Path(log_path), target, force, output)
    events = read_log(log_path)
    first = next(events, None)  # a file that is not an LCM log fails here, before anything is written
    sink = _Sink.rerun(target) if chosen == "rrd" else _Sink.mcap(target, schema)
    fitting = [route for route in config.routes if _reads_lcm(route) and sink.holds(route)]
    writes = _distinct([_narrowed(route, lcm_channels) for route in fitting])
    if not writes:
        raise ConvertError(f"no route of {config_name} reads LCM and writes {sink.what}")
    stop = stop or threading.Event()
    channels: set[str] = set()
    with partial_output(target) as partial:  # removed on a failure, kept (Interrupted) on a stop
        errors = _RouteErrors()
        router = Router(_into(config, writes, sink, partial), view=errors)
        written = router.transports[sink.transport]
        messages: Counter[str] = written.messages  # type: ignore[attr-defined]  # both file transports count
        try:
            size = Path(log_path).stat().st_size
            with _progress(size, progress) as advance:
                for event in itertools.chain([first] if first is not None else [], events):
                    if stop.is_set():
                        break
                    channels.add(event.channel)
                    router.feed("lcm", Received(event.channel, event.data, event.timestamp_us))
                    advance(len(event.data) + len(event.channel) + 36)  # roughly one event record
        finally:
            router.close()  # the file complete (or closed properly); each route's errors reported
        if stop.is_set():
            raise Interrupted(sum(messages.values()), partial)
        if not sum(messages.values()):  # an empty file would look like a result
            partial.unlink(missing_ok=True)
    chunks = dict(getattr(written, "chunks", {}))  # the rerun transport counts chunks per entity
    return Conversion(
        target, chosen, dict(messages), chunks, errors.skipped, tuple(sorted(channels)), lcm_channels
    )


@dataclass(frozen=True, slots=True)
class _Sink:
    """The write-only transport a conversion ends in: its name, its settings, what it holds."""

    transport: str
    settings: dict[str, Any]
    holds_type: Callable[[MessageType], bool]
    what: str

    @classmethod
    def mcap(cls, target: Path, schema: Profile) -> _Sink:
        from viewer_bridge.transports.mcap import McapTransport  # the foxglove extra, only for .mcap files

        return cls(
            "mcap",
            {"profile": schema},
            lambda kind: McapTransport.carries(kind, schema),
            f"the {schema} schema",
        )

    @classmethod
    def rerun(cls, target: Path) -> _Sink:
        rerun = TRANSPORTS.get("rerun")  # rerun-sdk: the rerun extra, only for .rrd files
        return cls("rerun", {"connect": None, "serve": False}, rerun.carries, "Rerun chunks")

    def holds(self, route: Route) -> bool:
        """Whether the file holds everything the route writes."""
        translator = TRANSLATORS.get(route.translator)
        return all(self.holds_type(written) for written in translator.writes(route.translator_options()))


def _reads_lcm(route: Route) -> bool:
    return all(read.encoding == LCM for read in TRANSLATORS.get(route.translator).reads)


def _distinct(routes: list[Route]) -> list[Route]:
    """The routes less those that would write what an earlier one writes into the file: the same
    source, translator, options and destination name, only to another transport live (the
    default config's /lcm/<channel> routes, one to ROS 2 and one to Foxglove, are one file's)."""
    seen: set[str] = set()
    distinct = []
    for route in routes:
        key = json.dumps(
            [route.source.name, route.translator, route.destination.name, route.options], sort_keys=True
        )
        if key not in seen:
            seen.add(key)
            distinct.append(route)
    return distinct


def _narrowed(route: Route, channels: str | None) -> Route:
    """A route of any LCM type (its outputs carry their definitions) that reads only the channels
    `channels` fully matches, besides its own pattern; other routes as they are.

    The source becomes `(?=(?:CHANNELS)\\Z)(?:SOURCE)`: CHANNELS' groups come first, so the
    destination's group numbers move past them."""
    generic = any(output.type.definition is not None for output in TRANSLATORS.get(route.translator).outputs)
    if channels is None or not generic:
        return route
    shift = re.compile(channels).groups
    destination = re.sub(
        r"\{([1-9][0-9]*)", lambda group: "{" + str(int(group[1]) + shift), route.destination.name
    )
    name = f"(?=(?:{channels})\\Z)(?:{route.source.name})"
    return route.model_copy(
        update={
            "source": route.source.model_copy(update={"name": name}),
            "destination": route.destination.model_copy(update={"name": destination}),
        }
    )


def _into(config: BridgeConfig, routes: list[Route], sink: _Sink, path: Path) -> BridgeConfig:
    """A config of `routes` (with `config`'s LCM types), read from LCM and written into `sink`'s file `path`.

    LCM is an in-process bus that is never started: the log's events are fed to the router by
    hand. No load cache: a load comes from the log, never from an earlier run.
    """
    return BridgeConfig.model_validate(
        {
            "lcm": {"url": "memq://"},
            # overwrite: a .partial left by an earlier run
            sink.transport: {**sink.settings, "path": path, "overwrite": True},
            "lcm_types": config.lcm_types,
            "drake_lcm_types": config.drake_lcm_types,
            "time": config.time,  # the file's log times and stamps: receive (the log's) or sim time
            "routes": [
                route.model_copy(
                    update={
                        "source": route.source.model_copy(update={"transport": "lcm"}),
                        "destination": Endpoint(transport=sink.transport, name=route.destination.name),
                    }
                )
                for route in routes
            ],
        }
    )


class _RouteErrors:
    """The router's status view for convert: per route, its errors and warnings, once at the end
    (each was logged as it happened, the first few in full); and what the routes held back
    (channels of no known type), by channel and kind, for `Conversion.skipped`."""

    def __init__(self) -> None:
        self.skipped: dict[tuple[str, str], int] = {}

    def show(self, snapshot: Snapshot) -> None:
        for name, stats in snapshot["routes"].items():
            counts = Counter(stats["errors"]) + Counter(stats["warnings"])
            if counts:
                log.warning("route %s: %s", name, dict(counts))
            for channel, kinds in stats.get("held", {}).items():
                for kind, count in kinds.items():  # each route sees every message of its channels: the most
                    self.skipped[channel, kind] = max(count, self.skipped.get((channel, kind), 0))

    def close(self) -> None:
        pass


def checked_output(log_path: Path, target: Path, force: bool, chosen: Format | None) -> Format:
    """The format to write `target` in (`output_format`), once `target` is known to be no input
    and no file to keep (`ConvertError` otherwise)."""
    _check_target(log_path, target, force)
    return output_format(target, chosen)


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


def _progress(total: int, shown: bool) -> contextlib.AbstractContextManager[Callable[[int], None]]:
    """The conversion's progress over the log's `total` bytes (`util/progress.py`), when `shown`."""
    if not shown:
        return contextlib.nullcontext(lambda size: None)
    return progress_of("viewer-bridge convert", "converting", total,
                       lambda done: f"{done / 1e6:.1f} of {total / 1e6:.1f} MB of the log")  # fmt: skip
