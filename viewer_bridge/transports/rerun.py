"""Rerun as a transport: write-only, one recording stream with one or several sinks at once.

* `connect`: a running viewer's gRPC URL (`rerun+http://127.0.0.1:9876/proxy`, where `rerun`
  listens). The SDK's gRPC client connects in the background and keeps what is logged until a
  viewer is there, so a viewer started after the bridge, or restarted, still gets the data; a
  viewer that never comes costs memory up to the SDK's buffer, and nothing else stops.
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
import threading
import uuid
from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from urllib.parse import quote

import rerun as rr
import rerun.blueprint as rrb

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

VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"  # what `rerun` listens on by default
_FLUSH_S = 10.0  # how long closing waits for the sinks to take what was logged

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
            self.partial = settings.path.with_name(settings.path.name + ".partial")
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
        self.stream = rr.RecordingStream(
            settings.application_id, recording_id=settings.recording_id or uuid.uuid4()
        )
        sinks: list[rr.sinks.LogSinkLike] = []
        if settings.connect:
            sinks.append(rr.GrpcSink(settings.connect))
        if settings.serve:
            sinks.append(
                rr.GrpcServerSink(
                    bind_ip=settings.host, port=self.grpc_port, server_memory_limit=settings.memory_limit
                )
            )
        if self.partial is not None:
            sinks.append(rr.FileSink(self.partial))
        self.stream.set_sinks(*sinks, default_blueprint=_blueprint(settings))
        if settings.serve:
            try:
                rr.serve_web_viewer(web_port=self.web_port, open_browser=False, connect_to=self.grpc_url)
            except RuntimeError as error:  # taken between the probe and now
                raise TransportUnavailable(f"rerun.web_port {self.web_port}: {error}") from None
        self._lock = threading.Lock()
        self.messages: Counter[str] = Counter()
        self.chunks: Counter[str] = Counter()  # chunks sent per entity path (what `convert` reports)

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
        stream, lock, messages, entities = self.stream, self._lock, self.messages, self.chunks

        def send(value: Chunks) -> None:
            chunks = value.chunks
            if prefix:
                chunks = [chunk.with_entity_path(prefix + chunk.entity_path.rstrip("/")) for chunk in chunks]
            rr.send_chunks(chunks, recording=stream)
            with lock:
                messages[name] += 1
                entities.update(chunk.entity_path for chunk in chunks)

        return ValuePublisher(Chunks, send)

    def describe(self) -> str:
        sinks = []
        if self.settings.connect:
            sinks.append(f"viewer {self.settings.connect}")
        if self.settings.serve:
            sinks.append(f"web viewer {self.web_url} (data {self.grpc_url})")
        if self.settings.path is not None:
            sinks.append(f"file {self.settings.path}")
        return "Rerun: " + ", ".join(sinks)

    def errors(self) -> Mapping[str, int]:
        return {}

    def close(self) -> None:
        try:
            self.stream.flush(timeout_sec=_FLUSH_S)
        except RuntimeError as error:  # a viewer that never came: the other sinks are flushed anyway
            log.warning("rerun: %s", error)
        self.stream.disconnect()  # the file's footer written, servers and connections closed
        if self.partial is not None and self.settings.path is not None:
            try:
                os.replace(self.partial, self.settings.path)
            except OSError as error:
                raise BridgeError(f"{self.settings.path}: {error.strerror or error}") from None
