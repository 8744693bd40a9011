"""The render server's fast paths against their slow references: the multipart parser against
Python's email package, and cached GPU meshes against a fresh upload in a new renderer."""

from __future__ import annotations

import json
import random
from email.parser import BytesParser
from email.policy import default
from typing import Any

import numpy as np
import pytest

from viewer_bridge.formats.gltf import read_gltf, write_gltf
from viewer_bridge.model.scene import Box, Capsule, Geometry, Link, Pose, Scene, Sphere
from viewer_bridge.render.renderer import Camera, Renderer
from viewer_bridge.render.server import BadRequest, parse_form


def email_parse_form(content_type: str, body: bytes) -> dict[str, bytes]:
    """The parser the server used before (the reference): the standard library's email package."""
    message = BytesParser(policy=default).parsebytes(
        b"Content-Type: " + content_type.encode() + b"\r\n\r\n" + body
    )
    fields: dict[str, bytes] = {}
    for part in message.iter_parts():
        name = part.get_param("name", header="content-disposition")
        payload = part.get_payload(decode=True)
        if isinstance(name, str):
            fields[name] = payload if isinstance(payload, bytes) else b""
    return fields


def multipart(parts: list[tuple[str, bytes]], boundary: str, preamble: bytes = b"") -> bytes:
    """A form as curl (Drake's client) writes it; a part's header line is given whole."""
    chunks = [preamble]
    for header, value in parts:
        chunks.append(f"--{boundary}\r\n{header}\r\n\r\n".encode() + value + b"\r\n")
    return b"".join(chunks) + f"--{boundary}--\r\n".encode()


GLTF = json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "data:,x"}]}).encode()
FORMS = [
    ("------------------------GaAlCHZ5Ns5WhdORTGMwic",
     [('Content-Disposition: form-data; name="width"', b"640"),
      ('Content-Disposition: form-data; name="scene"; filename="0001-color.gltf"\r\nContent-Type: model/gltf+json',
       GLTF)], b""),
    ("b", [('Content-Disposition: form-data; name="x"', b"a\r\nb--c\r\n--"),
           ('Content-Disposition: form-data; name="empty"', b"")], b"ignored preamble\r\n"),
    ("q", [('content-disposition: form-data; name="lower"', b"1"), ("Content-Type: text/plain", b"no name")], b""),
    ("with space", [('Content-Disposition: form-data; name="binary"', bytes(range(256)) * 4)], b""),
]  # fmt: skip


@pytest.mark.parametrize(("boundary", "parts", "preamble"), FORMS)
def test_forms_parse_as_the_email_package_parses_them(
    boundary: str, parts: list[tuple[str, bytes]], preamble: bytes
) -> None:
    content_type = f'multipart/form-data; boundary="{boundary}"'
    body = multipart(parts, boundary, preamble)
    parsed = parse_form(content_type, body)
    assert parsed == email_parse_form(content_type, body)
    assert parsed  # every form above has a named part


def test_cut_and_mutated_forms_raise_only_bad_request() -> None:
    rng = random.Random(5)
    boundary, parts, _ = FORMS[0]
    body = multipart(parts, boundary)
    outcomes = {"parsed": 0, "refused": 0}
    for _ in range(3000):
        data = bytearray(body[: rng.randrange(len(body) + 1)])
        for _ in range(rng.randrange(4)):
            if data:
                data[rng.randrange(len(data))] = rng.choice(b'\r\n-"=;ab\0')
        try:
            parse_form(f"multipart/form-data; boundary={boundary}", bytes(data))
            outcomes["parsed"] += 1
        except BadRequest:
            outcomes["refused"] += 1
    assert outcomes["refused"] > 500 and outcomes["parsed"] > 0  # anything else raised would fail here


def scene_bytes(offset: float) -> bytes:
    """A few shapes (a capsule is a mesh of its own) and a camera node looking at them."""
    geometries = (
        Geometry(Box((0.4, 0.3, 0.2)), Pose((offset, 0.0, -2.0)), (0.8, 0.2, 0.2, 1.0)),
        Geometry(Sphere(0.2), Pose((-0.4, 0.2, -2.5)), (0.2, 0.8, 0.2, 1.0)),
        Geometry(Capsule(0.1, 0.3), Pose((0.3, -0.3, -1.8), (0.9, 0.3, 0.3, 0.1)), (0.2, 0.2, 0.8, 1.0)),
    )
    document = json.loads(write_gltf(Scene((Link("things", 0, geometries),))))
    document["nodes"].append({"camera": 0, "matrix": np.eye(4).reshape(-1).tolist()})
    document["cameras"] = [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.01}}]
    document["scenes"][0]["nodes"].append(len(document["nodes"]) - 1)
    return json.dumps(document).encode()


def render(renderer: Renderer, offset: float, kind: str) -> Any:
    scene = read_gltf(scene_bytes(offset))
    assert scene.camera_matrix is not None
    camera = Camera(64, 48, 50.0, 50.0, 31.5, 23.5, 0.05, 10.0, scene.camera_matrix)
    return renderer.render(scene, camera, kind)


def test_cached_meshes_render_exactly_as_fresh_uploads() -> None:
    cached = Renderer()
    requests = [(0.0, "color"), (0.0, "depth"), (0.3, "label"), (0.0, "label"), (0.3, "color")]
    for offset, kind in requests:
        ours = render(cached, offset, kind)
        reference = render(Renderer(), offset, kind)  # a new context: every mesh uploaded anew
        assert np.array_equal(ours, reference), (offset, kind)
        assert ours[..., 0].min() != ours[..., 0].max()  # something was drawn
    # The sphere and capsule never move and the box has two places: 4 meshes uploaded in all.
    assert cached.meshes.misses == 4 and cached.meshes.hits == 11


def test_the_cache_is_bounded_by_bytes() -> None:
    renderer = Renderer(cache_bytes=20_000)
    for step in range(6):
        render(renderer, 0.1 * step, "label")
        assert renderer.meshes.entries.total <= 20_000 or len(renderer.meshes.entries) == 1
    assert renderer.meshes.entries.total == sum(entry.size for entry in renderer.meshes.entries.values())
    assert len(renderer.meshes.entries) < renderer.meshes.misses
