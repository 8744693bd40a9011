"""The render server's bounds, against the real server (`viewer-bridge serve-render`): requests at
once (`--max-requests`: 503 with Retry-After beyond), uploads held together (`--max-upload`: the
rest wait their turn unread), and the image size (`--max-image`: 400 naming the limit)."""

from __future__ import annotations

import http.client
import io
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from urllib.parse import urlsplit

import pytest

from tests.peers import wait_for
from tests.render.test_renderer import form, sample_gltf, start_server

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
BOUNDARY = "bounds"


def multipart(fields: dict[str, bytes]) -> bytes:
    parts = [f'--{BOUNDARY}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'.encode() + value + b"\r\n"
             for name, value in fields.items()]  # fmt: skip
    return b"".join(parts) + f"--{BOUNDARY}--\r\n".encode()


def post(url: str, body: bytes) -> tuple[int, dict[str, str], bytes]:
    """One POST /render: its status, headers and body."""
    where = urlsplit(url)
    connection = http.client.HTTPConnection(where.hostname or "127.0.0.1", where.port, timeout=60)
    try:
        connection.request(
            "POST", "/render", body, {"Content-Type": f"multipart/form-data; boundary={BOUNDARY}"}
        )
        response = connection.getresponse()
        return response.status, dict(response.getheaders()), response.read()
    finally:
        connection.close()


@contextmanager
def serving(*args: str) -> Iterator[str]:
    server, url = start_server(*args)
    try:
        yield url
    finally:
        server.terminate()
        server.wait(timeout=10)


def stalled_upload(url: str, length: int) -> socket.socket:
    """A request that says it uploads `length` bytes and sends 10 of them: it holds its place."""
    where = urlsplit(url)
    client = socket.create_connection((where.hostname or "127.0.0.1", where.port or 80), timeout=60)
    head = (f"POST /render HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data; boundary={BOUNDARY}\r\n"
            f"Content-Length: {length}\r\n\r\n")  # fmt: skip
    client.sendall(head.encode() + b"-" * 10)
    return client


def test_an_image_above_the_default_limit_is_refused_naming_it_never_rendered() -> None:
    """8192x8192 took 2.45 GB to render: refused (400) against the default 4096x4096."""
    with serving() as url:
        status, _, text = post(url, multipart(form(sample_gltf(), width=b"8192", height=b"8192")))
        assert status == 400 and b"at most 4096x4096" in text and b"--max-image" in text, text


def test_max_image_sets_the_largest_image() -> None:
    from PIL import Image

    with serving("--max-image", "64x48") as url:
        for width, height in ((65, 48), (64, 49)):
            status, _, text = post(url, multipart(form(sample_gltf(), width=str(width).encode(),
                                                       height=str(height).encode())))  # fmt: skip
            assert status == 400 and b"at most 64x48" in text, (width, height, text)
        status, _, png = post(url, multipart(form(sample_gltf(), width=b"64", height=b"48", center_x=b"31.5",
                                                  center_y=b"23.5")))  # fmt: skip
        assert status == 200 and Image.open(io.BytesIO(png)).size == (64, 48)


def test_requests_beyond_max_requests_are_answered_503_with_retry_after_and_served_again_later() -> None:
    with serving("--max-requests", "2") as url:
        held = [stalled_upload(url, 1000) for _ in range(2)]
        answers: list[tuple[int, dict[str, str], bytes]] = []

        def busy() -> bool:  # the two held requests are in once a third is refused
            answers.append(post(url, multipart(form(sample_gltf()))))
            return answers[-1][0] == 503

        try:
            assert wait_for(busy, 60), answers[-1]
            status, headers, text = answers[-1]
            assert headers.get("Retry-After") == "1" and b"--max-requests" in text, (headers, text)
        finally:
            for client in held:
                client.close()
        assert wait_for(
            lambda: post(url, multipart(form(sample_gltf())))[0] == 200, 60
        )  # the places are free


def test_uploads_together_stay_within_max_upload_and_the_rest_wait_their_turn_in_order() -> None:
    """`Admission` alone (what the server asks before it reads an upload), with real threads."""
    from viewer_bridge.render.server import Admission

    admission = Admission(max_requests=3, max_bytes=1000, wait_s=60)
    assert admission.enter(800)
    order: list[str] = []

    def request(name: str, length: int) -> None:
        if admission.enter(length):
            order.append(name)

    second = threading.Thread(target=request, args=("second", 800))
    second.start()
    assert wait_for(lambda: admission.requests == 2, 60)
    third = threading.Thread(target=request, args=("third", 100))  # it fits, but waits behind the second
    third.start()
    assert wait_for(lambda: admission.requests == 3, 60)
    assert not admission.enter(1)  # a fourth: over max_requests, refused at once
    time.sleep(0.2)  # nothing may enter meanwhile (a correct Admission never lets them: no flakiness)
    assert order == []
    admission.leave(800)
    second.join(60)
    assert wait_for(lambda: order == ["second", "third"], 60), order  # 800 + 100 fit together
    assert Admission(1, 1000, wait_s=0.05).enter(5000)  # a request alone always fits
    late = Admission(2, 1000, wait_s=0.05)
    assert late.enter(900) and not late.enter(200)  # its turn did not come within wait_s: refused
