"""Rerun as a transport: write-only, one recording stream with one or several sinks at once.

* `connect`: a running viewer's gRPC URL (`rerun+http://127.0.0.1:9876/proxy`, where `rerun`
  listens). Whether a viewer answers there is said at start (with how to start one). Until one
  does, what is logged is kept in the recording stream of the viewer (its own, `_Viewer`) and
  counted as undelivered (`unsent`, and the transport's `unsent_no_viewer`); the SDK's gRPC client
  is made once one answers (looked for every second), and gets what was kept. So a viewer started
  after the bridge still gets the data, and one that never comes costs no wait at close: the
  SDK's client, made and left unconnected, would wait 5 s for it when the stream closes.
* `serve`: the bridge serves the data itself over gRPC on `host:grpc_port` and the web viewer
  (HTML, JS and Wasm) on `web_port`: the start-up line prints the URL a browser opens. The gRPC
  server keeps up to `memory_limit` of data for late viewers; static data (the scene) is never
  dropped. The SDK's web-viewer server has no bind-address option and listens on every
  interface, but it serves only the viewer's files: the data stays on `host`. A port of 0 picks
  a free one. A port in use is refused at start, in one line.
* `path`: an `.rrd` file, written as `PATH.partial` and renamed to `PATH` when the bridge
  closes (refused at start if `PATH` exists, unless `overwrite`).

A route's destination name is the entity path its chunks are logged under (`/drake`), so the
translators' chunks (`viewer_bridge.formats.rerun`) name entities from the root. The translators
hand over the SDK's own chunks (a `Chunks` value, `viewer_bridge.formats.rerun.schema`), which go
to the SDK's `send_chunks` as they are; a publisher given bytes decodes them into chunks first.
"""

from __future__ import annotations

import errno
import logging
import os
import socket
import sys
import threading
import uuid
from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from urllib.parse import quote, urlsplit

# The SDK's own log lines (Rust's, on stderr) with no colour codes on a pipe or a file; RUST_LOG,
# if set, still says which. Before the SDK is imported: its logger is set up then.
if not sys.stderr.isatty():
    os.environ.setdefault("NO_COLOR", "1")

import rerun as rr  # noqa: E402
import rerun.blueprint as rrb  # noqa: E402

from viewer_bridge.errors import BridgeError, InvalidName, TransportUnavailable
from viewer_bridge.formats.rerun.schema import RERUN, Chunks
from viewer_bridge.transports.base import (
    Deliver,
    MessageType,
    Publisher,
    Qos,
    Transport,
    TransportSettings,
    ValuePublisher,
)
from viewer_bridge.util.partial import finish, partial_path

VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"  # what `rerun` listens on by default
_FLUSH_S = 10.0  # how long closing waits for the file and served sinks to take what was logged
_VIEWER_FLUSH_S = 1.0  # how long closing waits for a connected viewer to take the rest
_LOOK_EVERY_S = 1.0  # how often a viewer that has not answered is looked for

log = logging.getLogger("viewer_bridge")


class RerunSettings(TransportSettings):
    application_id: str = "viewer_bridge"  # how the viewer names and groups the recording
    recording_id: str | None = None  # None: a new recording per run
    connect: str | None = None  # a running viewer's gRPC URL, e.g. rerun+http://127.0.0.1:9876/proxy
    serve: bool = False  # serve the data over gRPC and the web viewer
    host: str = "127.0.0.1"  # where the gRPC server listens
    grpc_port: int = 9877  # 0: a free port (9877: not the 9876 a native viewer listens on)
    web_port: int = 9090  # 0: a free port
    memory_limit: str = "1GiB"  # data the gRPC server keeps for late viewers (static data always)
    # Where the 3D view's camera starts (Drake's z up), looking at `look_at`; None: the viewer frames
    # everything (with a ground half-space, that is 50 m across).
    eye: tuple[float, float, float] | None = (2.0, 2.0, 1.2)
    look_at: tuple[float, float, float] = (0.0, 0.0, 0.3)
    path: Path | None = None  # an .rrd file
    overwrite: bool = False  # replace the .rrd file if it exists (otherwise refused at start)


def _free_port(host: str, port: int, setting: str) -> int:
    """`port` if nothing listens on it (a free one for 0); `TransportUnavailable` if taken."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as error:
            reason = "in use" if error.errno == errno.EADDRINUSE else error.strerror
            raise TransportUnavailable(f"{host}:{port} ({setting}): {reason}") from error
        bound: int = probe.getsockname()[1]
        return bound


def _blueprint(settings: RerunSettings) -> rrb.Blueprint:
    """One 3D view of everything, z up, its camera where the settings say."""
    eye = None
    if settings.eye is not None:
        eye = rrb.EyeControls3D(position=settings.eye, look_target=settings.look_at, eye_up=(0.0, 0.0, 1.0))
    return rrb.Blueprint(rrb.Spatial3DView(origin="/", name="Drake", eye_controls=eye), collapse_panels=True)


def _address(url: str) -> tuple[str, int]:
    """The host and port a viewer's gRPC URL names (9876, a viewer's own, when it names none)."""
    parts = urlsplit(url)
    return parts.hostname or "127.0.0.1", parts.port or 9876


def _answers(address: tuple[str, int]) -> bool:
    """Whether something accepts a connection at `address` (a viewer's gRPC server)."""
    try:
        socket.create_connection(address, timeout=0.5).close()
    except OSError:
        return False
    return True


class _Viewer:
    """The `connect` sink: a recording stream of its own (the recording's id), which keeps what is
    logged until a viewer answers at `url` and then hands it all to the SDK's gRPC client."""

    def __init__(self, url: str, stream: rr.RecordingStream, blueprint: rrb.Blueprint) -> None:
        self.url = url
        self.stream = stream
        self._blueprint = blueprint
        self._address = _address(url)
        self.connected = threading.Event()
        self._stop = threading.Event()
        self.answered_at_start = _answers(self._address)
        if self.answered_at_start:
            self._connect()
        else:
            threading.Thread(target=self._look, name="rerun viewer", daemon=True).start()

    def _connect(self) -> None:
        self.stream.set_sinks(rr.GrpcSink(self.url), default_blueprint=self._blueprint)
        self.connected.set()

    def _look(self) -> None:
        while not self._stop.wait(_LOOK_EVERY_S):
            if _answers(self._address):
                self._connect()
                log.info(
                    "rerun: a viewer answered at %s: it gets what was kept for it (counted as unsent)",
                    self.url,
                )
                return

    def close(self) -> None:
        """Hand a connected viewer the rest (waiting at most `_VIEWER_FLUSH_S`); drop what no viewer took."""
        self._stop.set()
        if not self.connected.is_set():
            return
        try:
            self.stream.flush(timeout_sec=_VIEWER_FLUSH_S)
        except RuntimeError as error:  # a viewer gone since: what it did not take is lost
            log.warning("rerun: %s: %s", self.url, error)
        self.stream.disconnect()


class RerunTransport(Transport):
    """A Rerun recording stream to a viewer, a served web viewer and/or an .rrd file; publish only."""

    Settings = RerunSettings
    encodings = frozenset({RERUN})
    settings: RerunSettings

    def __init__(self, settings: RerunSettings) -> None:
        super().__init__(settings)
        if not (settings.connect or settings.serve or settings.path):
            raise TransportUnavailable(
                "the rerun transport has no sink: set rerun.connect, rerun.serve or rerun.path"
            )
        self.partial: Path | None = None
        if settings.path is not None:
            if settings.path.exists() and not settings.overwrite:
                raise TransportUnavailable(
                    f"{settings.path} exists (rerun.path): give another file, or replace it with "
                    "--set rerun.overwrite=true (in a config: rerun.overwrite: true)"
                )
            self.partial = partial_path(settings.path)  # itself when convert hands it its .partial
            try:
                self.partial.open("wb").close()  # a folder that cannot be written fails here, in one line
            except OSError as error:
                raise TransportUnavailable(
                    f"{settings.path} (rerun.path): {error.strerror or error}"
                ) from None
        self.grpc_port = self.web_port = 0
        if settings.serve:
            self.grpc_port = _free_port(settings.host, settings.grpc_port, "rerun.grpc_port")
            self.web_port = _free_port("0.0.0.0", settings.web_port, "rerun.web_port")  # the SDK binds all
        recording_id = settings.recording_id or uuid.uuid4()
        blueprint = _blueprint(settings)
        self.viewer: _Viewer | None = None
        if settings.connect:
            viewer_stream = rr.RecordingStream(settings.application_id, recording_id=recording_id)
            self.viewer = _Viewer(settings.connect, viewer_stream, blueprint)
            if not self.viewer.answered_at_start:
                log.warning(
                    "rerun: no viewer answers at %s: start one with `rerun` (it gets what was logged since; "
                    "until then it is counted as unsent), or serve a web viewer with --set rerun.serve=true",
                    settings.connect,
                )
        self.stream = rr.RecordingStream(settings.application_id, recording_id=recording_id)
        sinks: list[rr.sinks.LogSinkLike] = []
        if settings.serve:
            sinks.append(
                rr.GrpcServerSink(
                    bind_ip=settings.host, port=self.grpc_port, server_memory_limit=settings.memory_limit
                )
            )
        if self.partial is not None:
            sinks.append(rr.FileSink(self.partial))
        self.streams = [self.viewer.stream] if self.viewer is not None else []
        if sinks:
            self.stream.set_sinks(*sinks, default_blueprint=blueprint)
            self.streams.append(self.stream)
        if settings.serve:
            try:
                rr.serve_web_viewer(web_port=self.web_port, open_browser=False, connect_to=self.grpc_url)
            except RuntimeError as error:  # taken between the probe and now
                raise TransportUnavailable(f"rerun.web_port {self.web_port}: {error}") from None
        self._lock = threading.Lock()
        self.messages: Counter[str] = Counter()
        self.chunks: Counter[str] = Counter()  # chunks sent per entity path (what `convert` reports)
        self._publishers: list[Publisher] = []

    @property
    def grpc_url(self) -> str:
        """The served data's URL (what a native viewer or the web viewer connects to)."""
        return f"rerun+http://{self.settings.host}:{self.grpc_port}/proxy"

    @property
    def web_url(self) -> str:
        """The web viewer's URL, connected to the served data: what a browser opens."""
        return f"http://{self.settings.host}:{self.web_port}/?url={quote(self.grpc_url, safe='')}"

    @classmethod
    def check_source(cls, name: str) -> None:
        raise InvalidName("the rerun transport only writes; it cannot be a route's source")

    @classmethod
    def check_destination(cls, name: str) -> None:
        if not name.startswith("/"):
            raise InvalidName(
                f"a rerun destination is an entity path from the root, e.g. /drake (got {name!r})"
            )

    def subscribe(self, pattern: str, message_type: MessageType, qos: Qos, deliver: Deliver) -> None:
        raise TransportUnavailable("the rerun transport only writes")

    def publisher(self, name: str, message_type: MessageType, qos: Qos) -> Publisher:
        prefix = "" if name.strip("/") == "" else "/" + name.strip("/")
        streams, lock, messages, entities = self.streams, self._lock, self.messages, self.chunks
        # Undelivered: nothing but a viewer to send to, and none has answered yet.
        viewer_only = self.viewer.connected if self.viewer is not None and len(streams) == 1 else None

        def send(value: Chunks) -> None:
            chunks = value.chunks
            if prefix:
                chunks = [chunk.with_entity_path(prefix + chunk.entity_path.rstrip("/")) for chunk in chunks]
            for stream in streams:
                rr.send_chunks(chunks, recording=stream)
            with lock:
                messages[name] += 1
                entities.update(chunk.entity_path for chunk in chunks)
            if viewer_only is not None and not viewer_only.is_set():
                publisher.unsent += 1

        publisher = ValuePublisher(Chunks, send)
        self._publishers.append(publisher)
        return publisher

    def describe(self) -> str:
        sinks = []
        if self.viewer is not None:
            answered = "a viewer answered" if self.viewer.connected.is_set() else "no viewer answers yet"
            sinks.append(f"viewer {self.settings.connect} ({answered})")
        if self.settings.serve:
            sinks.append(f"web viewer {self.web_url} (data {self.grpc_url})")
        if self.settings.path is not None:
            sinks.append(f"file {self.settings.path}")
        return "Rerun: " + ", ".join(sinks)

    def errors(self) -> Mapping[str, int]:
        unsent = sum(publisher.unsent for publisher in self._publishers)
        return {"unsent_no_viewer": unsent} if unsent else {}

    def close(self) -> None:
        if self.viewer is not None:
            unsent = sum(publisher.unsent for publisher in self._publishers)
            if unsent and not self.viewer.connected.is_set():
                log.warning("rerun: no viewer answered at %s: the %d messages kept for it are dropped",
                            self.viewer.url, unsent)  # fmt: skip
            self.viewer.close()
        if self.stream in self.streams:
            try:
                self.stream.flush(timeout_sec=_FLUSH_S)
            except RuntimeError as error:
                log.warning("rerun: %s", error)
            self.stream.disconnect()  # the file's footer written, servers closed
        if self.partial is not None and self.settings.path is not None and self.partial != self.settings.path:
            try:  # a live session's (convert renames its own)
                finish(self.partial, self.settings.path, sum(self.messages.values()))
            except OSError as error:
                raise BridgeError(f"{self.settings.path}: {error.strerror or error}") from None
