"""Drake's glTF render API, served: `POST /render` (docs/PROTOCOLS.md section 5).

The multipart form carries the scene (glTF with embedded buffers), its sha256, the image type
and the camera. Replies: a PNG (8-bit RGB colour or label, 16-bit millimetre depth), 400 with a
plain-text reason for a bad request, 500 for anything else. GL work happens on one thread;
concurrent requests queue for it. Uploads above `max_upload` bytes are refused unread, and so is
a post from a browser page of a foreign origin (403; viewer_bridge/transports/origins.py: no
`Origin` header, as from Drake's client, and loopback pages pass, and the `allowed_origins`).

Every request is bounded before its upload is read (`Admission`): at most `max_requests` at once,
the rest answered 503 with a Retry-After; of those, the uploads read and held together stay within
`max_upload` (the others wait their turn, in order, unread). An image larger than `max_image`
(width by height) is refused with a 400 naming the limit, never rendered: the renderer's memory
grows with the pixels (an 8192x8192 render took the server to 3.9 GB).
"""

from __future__ import annotations

import hashlib
import http.server
import io
import itertools
import logging
import queue
import re
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import Future
from typing import Any

import numpy as np
from PIL import Image

from viewer_bridge.errors import BadRequest, GltfError
from viewer_bridge.formats.gltf import read_gltf
from viewer_bridge.render.renderer import Camera, Renderer, depth_mm, rgb8
from viewer_bridge.transports.origins import OriginGate, Origins

log = logging.getLogger("viewer_bridge")

DEFAULT_MAX_UPLOAD = 256 * 1024 * 1024
DEFAULT_MAX_REQUESTS = 8  # at once: being read, waiting for the GL thread, rendering, or waiting to be read
DEFAULT_MAX_IMAGE = (4096, 4096)  # width, height
ADMISSION_WAIT_S = 60.0  # how long a request waits for its upload's turn before a 503
RETRY_AFTER_S = 1  # what a refused client is told to wait (Drake's cameras render one at a time)
_NUMBERS = ("width", "height", "near", "far", "focal_x", "focal_y", "center_x", "center_y")


_BOUNDARY = re.compile(r'boundary=(?:"([^"]+)"|([^;\s]+))', re.IGNORECASE)
_NAME = re.compile(rb'(?:^|;)\s*name="([^"]*)"', re.IGNORECASE)


def parse_form(content_type: str, body: bytes) -> dict[str, bytes]:
    """The fields of a multipart/form-data body (RFC 7578), by name.

    Split on the boundary with `bytes.find`: the generic email parser reads a 3 MB scene line by
    line and took most of a request's time. Parts without a name are skipped, as before.
    """
    if not content_type.startswith("multipart/form-data"):
        raise BadRequest("expected a multipart/form-data POST")
    match = _BOUNDARY.search(content_type)
    if match is None:
        raise BadRequest("the form could not be parsed")
    delimiter = b"--" + (match.group(1) or match.group(2)).encode("latin-1")
    start = body.find(delimiter)
    if start < 0:
        raise BadRequest("the form could not be parsed")
    fields: dict[str, bytes] = {}
    separator = b"\r\n" + delimiter
    position = start + len(delimiter)
    while not body.startswith(b"--", position):  # "--" after a delimiter closes the form
        head_start = body.find(b"\r\n", position) + 2
        end = body.find(separator, head_start)
        head_end = body.find(b"\r\n\r\n", head_start - 2, end)
        if head_start < 2 or end < 0 or head_end < 0:
            raise BadRequest("the form could not be parsed")
        name = _part_name(body[head_start:head_end])
        if name is not None:
            fields[name] = body[head_end + 4 : end]
        position = end + len(separator)
    return fields


def _part_name(head: bytes) -> str | None:
    """The `name` of a part's Content-Disposition header, if it has one."""
    for line in head.split(b"\r\n"):
        key, _, value = line.partition(b":")
        if key.strip().lower() == b"content-disposition":
            match = _NAME.search(value)
            return match.group(1).decode("utf-8", "replace") if match else None
    return None


def render_request(
    fields: dict[str, bytes],
    render: Callable[[Any, Camera, str], np.ndarray[Any, Any]],
    max_image: tuple[int, int] = DEFAULT_MAX_IMAGE,
) -> bytes:
    """The PNG answering one form; raises `BadRequest` for what the client got wrong, or for an
    image wider or taller than `max_image` (width, height)."""
    for name in ("scene", "scene_sha256", "image_type", *_NUMBERS):
        if name not in fields:
            raise BadRequest(f"missing form field {name!r}")
    if (
        hashlib.sha256(fields["scene"]).hexdigest()
        != fields["scene_sha256"].decode("ascii", "replace").strip()
    ):
        raise BadRequest("scene_sha256 does not match the uploaded scene")
    kind = fields["image_type"].decode("ascii", "replace")
    if kind not in ("color", "depth", "label"):
        raise BadRequest(f"unsupported image_type {kind!r} (color, depth or label)")
    numbers = {name: _number(fields, name) for name in _NUMBERS}
    width, height = int(numbers["width"]), int(numbers["height"])
    max_width, max_height = max_image
    if (
        width != numbers["width"]
        or height != numbers["height"]
        or not (0 < width <= max_width and 0 < height <= max_height)
    ):
        raise BadRequest(
            f"width and height must be whole numbers, at most {max_width}x{max_height} (the server's "
            f"limit, serve-render --max-image WIDTHxHEIGHT); asked for {_text(fields['width'])}x{_text(fields['height'])}"
        )
    if not 0 < numbers["near"] < numbers["far"] or numbers["focal_x"] <= 0 or numbers["focal_y"] <= 0:
        raise BadRequest("need 0 < near < far and positive focal lengths")
    try:
        scene = read_gltf(fields["scene"])
    except GltfError as error:
        raise BadRequest(f"scene: {error}") from None
    if scene.camera_matrix is None:
        raise BadRequest("scene: no camera node")
    rotation = scene.camera_matrix[:3, :3]
    if not np.isfinite(scene.camera_matrix).all() or abs(np.linalg.det(rotation)) < 1e-9:
        raise BadRequest("scene: the camera node's matrix is not an invertible transform")
    camera = Camera(width, height, numbers["focal_x"], numbers["focal_y"], numbers["center_x"], numbers["center_y"],
                    numbers["near"], numbers["far"], scene.camera_matrix)  # fmt: skip
    image = render(scene, camera, kind)
    if kind == "depth":
        low, high = _number(fields, "min_depth"), _number(fields, "max_depth")
        pixels = Image.fromarray(depth_mm(image, low, high))
    else:
        pixels = Image.fromarray(rgb8(image), "RGB")
    out = io.BytesIO()
    pixels.save(out, format="PNG")
    return out.getvalue()


def _text(value: bytes) -> str:
    """A form value as the client sent it, in a reason (at most 20 characters)."""
    return value[:20].decode(errors="replace")


def _number(fields: dict[str, bytes], name: str) -> float:
    if name not in fields:
        raise BadRequest(f"missing form field {name!r}")
    try:
        value = float(fields[name])
    except ValueError:
        raise BadRequest(f"{name} is not a number: {fields[name][:40]!r}") from None
    if not np.isfinite(value):
        raise BadRequest(f"{name} is not finite")
    return value


class RenderThread:
    """The one thread that owns the GL context; `render` queues a job and waits for it."""

    def __init__(self) -> None:
        self._jobs: queue.Queue[tuple[Any, Camera, str, Future[np.ndarray[Any, Any]]]] = queue.Queue()
        self._ready: Future[None] = Future()
        threading.Thread(target=self._run, name="render", daemon=True).start()
        self._ready.result(timeout=30)

    def _run(self) -> None:
        try:
            renderer = Renderer()
        except Exception as error:  # no GL: say so to whoever waits
            self._ready.set_exception(error)
            return
        self._ready.set_result(None)
        while True:
            scene, camera, kind, future = self._jobs.get()
            try:
                future.set_result(renderer.render(scene, camera, kind))
            except Exception as error:
                future.set_exception(error)

    def render(self, scene: Any, camera: Camera, kind: str) -> np.ndarray[Any, Any]:
        future: Future[np.ndarray[Any, Any]] = Future()
        self._jobs.put((scene, camera, kind, future))
        return future.result()


class Admission:
    """Which requests may read their upload now: at most `max_requests` at once (`enter` says False
    beyond: 503), and of those, uploads holding at most `max_bytes` together; the others wait, in
    arrival order, unread, until theirs fits (a request alone always fits: `max_upload` refused
    larger ones before) or `wait_s` passes (False)."""

    def __init__(self, max_requests: int, max_bytes: int, wait_s: float = ADMISSION_WAIT_S) -> None:
        self._max_requests = max_requests
        self._max_bytes = max_bytes
        self._wait_s = wait_s
        self._requests = 0  # in: waiting or admitted
        self._bytes = 0  # the uploads of the admitted ones
        self._queue: list[object] = []  # the waiting ones' tickets, first come first
        self._changed = threading.Condition()

    @property
    def requests(self) -> int:
        """The requests in now: waiting or admitted."""
        with self._changed:
            return self._requests

    def enter(self, length: int) -> bool:
        """Whether a request with an upload of `length` bytes is in (then `leave` it): False when
        `max_requests` are in already, or when its turn did not come within `wait_s`."""
        ticket = object()
        with self._changed:
            if self._requests >= self._max_requests:
                return False
            self._requests += 1
            self._queue.append(ticket)
            fits = self._changed.wait_for(
                lambda: (
                    self._queue[0] is ticket and (self._bytes == 0 or self._bytes + length <= self._max_bytes)
                ),
                self._wait_s,
            )
            self._queue.remove(ticket)
            if not fits:
                self._requests -= 1
            else:
                self._bytes += length
            self._changed.notify_all()
            return fits

    def leave(self, length: int) -> None:
        """A request let in by `enter(length)` is done: its upload is let go."""
        with self._changed:
            self._requests -= 1
            self._bytes -= length
            self._changed.notify_all()


def render_gate(allowed_origins: Iterable[str] = ()) -> OriginGate:
    """The render server's origin check: loopback pages and `allowed_origins` (Drake's client sends no Origin)."""
    return OriginGate(
        Origins(allowed_origins), "render request", lambda origin: f"serve-render --allow-origin '{origin}'"
    )


def make_server(
    host: str = "127.0.0.1",
    port: int = 8000,
    max_upload: int = DEFAULT_MAX_UPLOAD,
    allowed_origins: Iterable[str] = (),
    max_requests: int = DEFAULT_MAX_REQUESTS,
    max_image: tuple[int, int] = DEFAULT_MAX_IMAGE,
) -> http.server.ThreadingHTTPServer:
    renderer = RenderThread()
    gate = render_gate(allowed_origins)
    admission = Admission(max_requests, max_upload)
    busy_refusals = itertools.count(1)  # the handlers' threads count here (`next` is atomic)

    class Handler(http.server.BaseHTTPRequestHandler):
        timeout = 30  # seconds a stalled upload may hold its connection's thread

        def do_POST(self) -> None:  # noqa: N802 - the http.server name
            refusal = gate.refusal(self.headers.get_all("Origin") or [])
            if refusal is not None:  # before anything is read: a foreign page gets nothing of ours
                self.close_connection = True
                return self._reply(refusal.status, f"{refusal}\n".encode(), "text/plain; charset=utf-8")
            if self.path.split("?")[0] != "/render":
                return self._reply(404, b"only POST /render is served", "text/plain")
            try:
                length = int(self.headers.get("Content-Length", ""))
            except ValueError:
                return self._reply(400, b"Content-Length is required", "text/plain")
            if not 0 <= length <= max_upload:
                return self._reply(
                    400, f"upload of {length} bytes is above the limit of {max_upload}".encode(), "text/plain"
                )
            if not admission.enter(length):  # unread: the client may send it again later
                self.close_connection = True
                refused = next(busy_refusals)
                if refused == 1 or refused % 1000 == 0:  # never a line per refusal
                    log.warning(
                        "render server: busy, %d requests refused so far (--max-requests %d)",
                        refused,
                        max_requests,
                    )
                busy = f"busy: {max_requests} requests at once is the limit (serve-render --max-requests); retry\n"
                return self._reply(503, busy.encode(), "text/plain", {"Retry-After": str(RETRY_AFTER_S)})
            try:
                self._serve(length)
            finally:
                admission.leave(length)

        def _serve(self, length: int) -> None:
            """Read, render and answer an admitted request."""
            try:
                body = self.rfile.read(length)
            except OSError:  # stalled past `timeout`, or reset by the client
                body = b""
            if len(body) < length:  # the client left mid-upload: nobody to answer, nothing to render
                log.info("render server: a client left after %d of %d bytes", len(body), length)
                return
            started = time.perf_counter()
            try:
                fields = parse_form(self.headers.get("Content-Type", ""), body)
                png = render_request(fields, renderer.render, max_image)
            except BadRequest as error:
                return self._reply(400, str(error).encode(), "text/plain")
            except Exception as error:
                log.exception("render failed")
                return self._reply(500, f"render failed: {error!r}".encode(), "text/plain")
            self._reply(200, png, "image/png")
            log.info(
                "rendered %s %sx%s in %.1f ms",
                fields["image_type"].decode(), fields["width"].decode(), fields["height"].decode(),
                (time.perf_counter() - started) * 1e3,
            )  # fmt: skip

        def _reply(
            self, status: int, body: bytes, content_type: str, headers: dict[str, str] | None = None
        ) -> None:
            self.send_response(status)
            for name, value in (headers or {}).items():
                self.send_header(name, value)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(body)))
            if self.close_connection:
                self.send_header("Connection", "close")
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the http.server signature
            log.debug("render server: " + format, *args)

    return http.server.ThreadingHTTPServer((host, port), Handler)
