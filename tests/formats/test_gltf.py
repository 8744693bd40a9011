"""glTF 2.0 in and out of the scene model."""

from __future__ import annotations

import base64
import json
import struct

import numpy as np
import pytest

from viewer_bridge.errors import GltfError
from viewer_bridge.formats.gltf import read_gltf, write_gltf
from viewer_bridge.model.lowering import triangle_mesh
from viewer_bridge.model.scene import Box, Geometry, Link, LinkPoses, Pose, Scene, Sphere, TriangleMesh


def scene() -> Scene:
    links = (
        Link("plant::a", 1, (Geometry(Box((1.0, 2.0, 3.0)), Pose((0.0, 0.0, 1.0)), (1.0, 0.0, 0.0, 1.0)),)),
        Link("plant::b", 1, (Geometry(Sphere(0.5), Pose(), (0.0, 1.0, 0.0, 0.5)),)),
    )
    poses = LinkPoses(0, ("plant::a", "plant::b"), np.ones(2, np.int32), np.array([[1.0, 0, 0], [0, 2.0, 0]]),
                      np.array([[0.0, 0, 0, 1.0], [1.0, 0, 0, 0]]))  # fmt: skip
    return Scene(links, poses)


def test_a_scene_written_reads_back_in_the_world_frame() -> None:
    back = read_gltf(write_gltf(scene()))
    assert [m.name for m in back.meshes] == ["plant::a", "plant::b"] and back.camera_matrix is None
    box = triangle_mesh(Box((1.0, 2.0, 3.0)))
    # plant::a: rotated 180 degrees about z, at x = 1; the box 1 m up in the link frame.
    expected = box.vertices * [-1, -1, 1] + [1.0, 0.0, 1.0]
    np.testing.assert_allclose(back.meshes[0].vertices, expected, atol=1e-6)
    assert back.meshes[0].color == (1.0, 0.0, 0.0, 1.0) and back.meshes[1].color == (0.0, 1.0, 0.0, 0.5)
    assert len(back.to_scene().links) == 2


def test_glb_is_the_same_document_in_binary() -> None:
    data = write_gltf(scene(), binary=True)
    magic, version, length = struct.unpack_from("<4sII", data)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, kind = struct.unpack_from("<I4s", data, 12)
    document = json.loads(data[20 : 20 + json_length])
    assert kind == b"JSON" and len(document["meshes"]) == 2 and "uri" not in document["buffers"][0]


def test_glb_reads_back_as_the_json_document_does() -> None:
    glb, text = read_gltf(write_gltf(scene(), binary=True)), read_gltf(write_gltf(scene()))
    assert [m.name for m in glb.meshes] == [m.name for m in text.meshes] == ["plant::a", "plant::b"]
    for ours, theirs in zip(glb.meshes, text.meshes, strict=True):
        np.testing.assert_array_equal(ours.vertices, theirs.vertices)
        np.testing.assert_array_equal(ours.triangles, theirs.triangles)
        assert ours.color == theirs.color


@pytest.mark.parametrize(
    ("cut", "reason"),
    [
        (lambda d: d[:10], "shorter than its 12-byte header"),
        (lambda d: d[:-4], "length"),
        (lambda d: d[:12] + struct.pack("<I4s", 8, b"BIN\0") + d[20:], "not JSON|past the end"),
        (lambda d: d[:8] + struct.pack("<I", 30) + d[12:30], "past the end|cut off"),
    ],
)
def test_a_broken_glb_is_a_gltf_error(cut: object, reason: str) -> None:
    data = cut(write_gltf(scene(), binary=True))  # type: ignore[operator]
    with pytest.raises(GltfError, match=reason):
        read_gltf(data)


def test_hierarchy_trs_and_the_camera() -> None:
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f4").tobytes()
    document = {
        "buffers": [{"byteLength": 36, "uri": "data:;base64," + base64.b64encode(positions).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"children": [1, 2], "translation": [0, 0, 5]},
                  {"mesh": 0, "scale": [2, 2, 2], "rotation": [0, 0, 0.7071067811865476, 0.7071067811865476]},
                  {"camera": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 10, 1]}],
        "scenes": [{"nodes": [0]}],
    }  # fmt: skip
    back = read_gltf(json.dumps(document).encode())
    np.testing.assert_allclose(back.meshes[0].vertices, [[0, 0, 5], [0, 2, 5], [-2, 0, 5]], atol=1e-9)
    assert back.meshes[0].triangles.tolist() == [[0, 1, 2]]
    assert (
        back.camera_matrix is not None and back.camera_matrix[2, 3] == 15.0
    )  # column-major, under the parent


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        (lambda d: d["buffers"][0].update(uri="file:///etc/passwd"), "only embedded data: URIs"),
        (lambda d: d["accessors"][0].update(count=2**31), "not valid"),
        (lambda d: d["accessors"][0].update(count=10_000), "do not fit"),
        (lambda d: d["nodes"][0].update(children=[0]), "reached twice"),
        (lambda d: d["nodes"][0].update(children=[1, 1]), "reached twice"),  # shared children: exponential
        (lambda d: d.update(scene=-1), "scene: -1 is not an index"),
        (lambda d: d["meshes"][0]["primitives"][0].update(mode=1), "only triangles"),
        (lambda d: d["nodes"][1].update(matrix=[1] * 15), "16 numbers"),
    ],
)
def test_malformed_documents_raise_gltf_errors(change: object, reason: str) -> None:
    document = json.loads(write_gltf(Scene((Link("a", 0, (Geometry(Box((1.0, 1.0, 1.0))),)),))))
    document["nodes"].insert(0, {"children": [1]})
    document["scenes"][0]["nodes"] = [0]
    change(document)  # type: ignore[operator]
    with pytest.raises(GltfError, match=reason):
        read_gltf(json.dumps(document).encode())


def test_large_payloads_are_decoded_once_and_the_cache_stays_bounded() -> None:
    from viewer_bridge.formats.gltf import _RecentPayloads

    cache = _RecentPayloads(max_bytes=1_000_000)
    blobs = [bytes([index]) * 300_000 for index in range(4)]
    texts = [base64.b64encode(blob).decode() for blob in blobs]
    first = cache.decode(texts[0])
    assert first == blobs[0]
    assert cache.decode(texts[0]) is first  # the same text: the decoded bytes of the first time
    for text, blob in zip(texts, blobs, strict=True):
        assert cache.decode(text) == blob
    assert cache.entries.total <= cache.entries.max_size  # 700 kB of text and data each: the newest is kept
    assert cache.entries.keys() == [texts[-1]]
    small = base64.b64encode(b"tiny").decode()
    assert cache.decode(small) == b"tiny" and small not in cache.entries
    with pytest.raises(ValueError):
        cache.decode("!" * 100_000)  # not base64: refused as before, and nothing kept
    assert "!" * 100_000 not in cache.entries


def test_a_large_buffer_read_twice_gives_the_same_meshes() -> None:
    rng = np.random.default_rng(3)
    mesh = TriangleMesh(rng.uniform(-1, 1, (20_000, 3)), rng.integers(0, 20_000, (20_000, 3)))
    document = write_gltf(
        Scene((Link("big", 0, (Geometry(mesh, Pose((1.0, 2.0, 3.0)), (0.1, 0.2, 0.3, 1.0)),)),))
    )
    assert len(document) > 2 * 64 * 1024  # the payload is cached
    first, second = read_gltf(document), read_gltf(document)
    np.testing.assert_allclose(first.meshes[0].vertices, mesh.vertices + (1.0, 2.0, 3.0), atol=1e-6)
    np.testing.assert_array_equal(second.meshes[0].vertices, first.meshes[0].vertices)
    np.testing.assert_array_equal(second.meshes[0].triangles, mesh.triangles)
