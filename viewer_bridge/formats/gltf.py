"""glTF 2.0 to and from the scene model (embedded `data:` buffers only).

Reading (`read_gltf`) flattens the node hierarchy: every triangle primitive becomes a mesh in
world coordinates (node matrices or TRS composed from the root) with its material's
baseColorFactor, and the camera node's world matrix is kept. This is what Drake's
RenderEngineGltfClient sends (docs/PROTOCOLS.md section 5). Everything is checked against the
buffers before use; a document that does not hold together raises `GltfError` naming where.

Writing (`write_gltf`) turns a scene into a self-contained glTF: one node per geometry with its
world matrix, shapes tessellated with `viewer_bridge.model.lowering.triangle_mesh` (point clouds, triads and
lines have no triangles: `SceneError`).
"""

from __future__ import annotations

import base64
import json
import struct
import threading
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from viewer_bridge.errors import GltfError
from viewer_bridge.model.lowering import triangle_mesh
from viewer_bridge.model.pose_math import rotation_matrix
from viewer_bridge.model.scene import FloatArray, Geometry, Link, Pose, Scene, TriangleMesh
from viewer_bridge.model.skipped import per_geometry
from viewer_bridge.util.lru import SizedLru

_COMPONENTS = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_MAX_ELEMENTS = 50_000_000  # no accessor may claim more: a bound on memory, whatever the header says


@dataclass(frozen=True)
class GltfMesh:
    vertices: FloatArray  # N x 3, world frame
    triangles: np.ndarray[Any, Any]  # M x 3 uint32
    color: tuple[float, float, float, float]
    name: str = ""


@dataclass(frozen=True)
class GltfScene:
    meshes: list[GltfMesh] = field(default_factory=list)
    camera_matrix: FloatArray | None = None  # the camera node's world matrix (4 x 4)

    def to_scene(self) -> Scene:
        """As the neutral scene: a link per mesh, vertices in the world frame."""
        links = tuple(
            Link(mesh.name or f"mesh{index}", 0, (Geometry(TriangleMesh(mesh.vertices, mesh.triangles.astype(np.int64)),
                                                           Pose(), mesh.color),))
            for index, mesh in enumerate(self.meshes)
        )  # fmt: skip
        return Scene(links)


def read_gltf(data: bytes) -> GltfScene:
    """A glTF 2.0 document, JSON (with `data:` buffers) or binary (`.glb`: the JSON chunk and its
    BIN chunk, which the first buffer without a `uri` stands for), as meshes in the world and a camera.

    Raises `GltfError` for anything that does not hold together; the specific checks name the
    part, and a last net turns any other inconsistency into a `GltfError` too.
    """
    try:
        return _read(data)
    except GltfError:
        raise
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError) as error:
        raise GltfError(f"malformed glTF: {type(error).__name__}: {error}") from None


def _read(data: bytes) -> GltfScene:
    text, binary = _glb_chunks(data) if data[:4] == _GLB_MAGIC else (data, None)
    try:
        document = json.loads(text)
    except (ValueError, UnicodeDecodeError) as error:
        raise GltfError(f"not JSON: {error}") from None
    if not isinstance(document, dict):
        raise GltfError("the document is not a JSON object")
    buffers = [_buffer(item, index, binary) for index, item in enumerate(_list(document, "buffers"))]
    reader = _Accessors(document, buffers)
    meshes: list[GltfMesh] = []
    camera: FloatArray | None = None
    nodes = _list(document, "nodes")
    scenes = _list(document, "scenes")
    scene_index = _index(document.get("scene", 0), max(len(scenes), 1), "scene")
    roots = (
        _list(scenes[scene_index], "nodes", f"scenes[{scene_index}]") if scenes else list(range(len(nodes)))
    )
    # Depth first, in document order (children pushed in reverse), so meshes come out in order.
    stack: list[tuple[int, FloatArray, int]] = [
        (_index(root, len(nodes), "scene node"), np.eye(4), 0) for root in reversed(roots)
    ]
    seen: set[int] = set()
    while stack:
        index, parent, depth = stack.pop()
        if depth > 64:
            raise GltfError("the node hierarchy is deeper than 64 (or has a cycle)")
        if index in seen:  # glTF nodes have one parent: a node reached twice is a cycle or a trap
            raise GltfError(f"nodes[{index}] is reached twice: a node may have only one parent")
        seen.add(index)
        node = nodes[index]
        if not isinstance(node, dict):
            raise GltfError(f"nodes[{index}] is not an object")
        world = parent @ _local_matrix(node, index)
        if "camera" in node:
            camera = world
        if "mesh" in node:
            meshes += _mesh(document, reader, _index(node["mesh"], len(_list(document, "meshes")), f"nodes[{index}].mesh"),
                            world, str(node.get("name", "")))  # fmt: skip
        for child in reversed(_list(node, "children", f"nodes[{index}]")):
            stack.append((_index(child, len(nodes), f"nodes[{index}].children"), world, depth + 1))
    return GltfScene(meshes, camera)


def _list(parent: Any, key: str, where: str = "") -> list[Any]:
    value = parent.get(key, []) if isinstance(parent, dict) else None
    if not isinstance(value, list):
        raise GltfError(f"{where + '.' if where else ''}{key} is not a list")
    return value


def _index(value: Any, count: int, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < count:
        raise GltfError(f"{where}: {value!r} is not an index below {count}")
    return value


_GLB_MAGIC = b"glTF"
_GLB_HEADER = struct.Struct("<4sII")  # magic, version, total length
_GLB_CHUNK = struct.Struct("<I4s")  # chunk length, type


def _glb_chunks(data: bytes) -> tuple[bytes, bytes | None]:
    """A `.glb`'s JSON chunk and its BIN chunk (None without one), checked against the lengths."""
    if len(data) < _GLB_HEADER.size:
        raise GltfError("a binary glTF shorter than its 12-byte header")
    _, version, length = _GLB_HEADER.unpack_from(data)
    if version != 2 or length != len(data):
        raise GltfError(f"binary glTF header: version {version}, length {length} for {len(data)} bytes")
    chunks: list[tuple[bytes, bytes]] = []
    offset = _GLB_HEADER.size
    while offset < length:
        if offset + _GLB_CHUNK.size > length:
            raise GltfError(f"binary glTF: a chunk header cut off at byte {offset}")
        size, kind = _GLB_CHUNK.unpack_from(data, offset)
        start = offset + _GLB_CHUNK.size
        if start + size > length:
            raise GltfError(f"binary glTF: the chunk at byte {offset} claims {size} bytes past the end")
        chunks.append((kind, data[start : start + size]))
        offset = start + size
    if not chunks or chunks[0][0] != b"JSON":
        raise GltfError("binary glTF: the first chunk is not JSON")
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == b"BIN\0" else None
    return chunks[0][1], binary


def _buffer(item: Any, index: int, binary: bytes | None = None) -> bytes:
    if isinstance(item, dict) and "uri" not in item and index == 0 and binary is not None:
        if len(binary) < int(item.get("byteLength", 0) or 0):
            raise GltfError(f"buffers[0]: the BIN chunk holds {len(binary)} bytes, fewer than its byteLength")
        return binary
    uri = item.get("uri") if isinstance(item, dict) else None
    if not isinstance(uri, str) or not uri.startswith("data:"):
        raise GltfError(f"buffers[{index}]: only embedded data: URIs are read")
    header, _, payload = uri.partition(",")
    if not header.endswith(";base64"):
        raise GltfError(f"buffers[{index}]: the data: URI is not base64")
    try:
        data = _RECENT_PAYLOADS.decode(payload)
    except ValueError as error:
        raise GltfError(f"buffers[{index}]: not base64 ({error})") from None
    if len(data) < int(item.get("byteLength", 0) or 0):
        raise GltfError(f"buffers[{index}]: {len(data)} bytes, fewer than its byteLength")
    return data


class _RecentPayloads:
    """Decoded base64 payloads by their text: the most recent, up to `max_bytes` of text and data.

    A render client sends every mesh again with each request (Drake's RenderEngineGltfClient
    posts the whole scene per image), and decoding megabytes of base64 was half the time of
    reading such a document. Small payloads are decoded each time: they cost less than a lookup.
    """

    SMALLEST = 64 * 1024  # characters

    def __init__(self, max_bytes: int) -> None:
        self.entries: SizedLru[str, bytes] = SizedLru(max_bytes)  # sized by text + data
        self._lock = threading.Lock()  # the render server reads documents on several threads

    def decode(self, payload: str) -> bytes:
        """`base64.b64decode(payload, validate=True)`, from the cache when the text was seen."""
        if len(payload) < self.SMALLEST:
            return base64.b64decode(payload, validate=True)
        with self._lock:
            data = self.entries.get(payload)
        if data is None:
            data = base64.b64decode(payload, validate=True)
            with self._lock:
                self.entries.put(payload, data, len(payload) + len(data))
        return data


_RECENT_PAYLOADS = _RecentPayloads(max_bytes=256 * 1024 * 1024)


class _Accessors:
    def __init__(self, document: dict[str, Any], buffers: list[bytes]) -> None:
        self.accessors = _list(document, "accessors")
        self.views = _list(document, "bufferViews")
        self.buffers = buffers

    def read(self, index: Any, where: str) -> np.ndarray[Any, Any]:
        accessor = self.accessors[_index(index, len(self.accessors), where)]
        name = f"accessors[{index}]"
        if not isinstance(accessor, dict):
            raise GltfError(f"{name} is not an object")
        dtype = _COMPONENTS.get(accessor.get("componentType"))  # type: ignore[arg-type]
        width = _WIDTHS.get(accessor.get("type"))  # type: ignore[arg-type]
        count = accessor.get("count")
        if dtype is None or width is None or not isinstance(count, int) or not 0 <= count <= _MAX_ELEMENTS:
            raise GltfError(f"{name}: componentType, type or count is not valid")
        view = self.views[_index(accessor.get("bufferView"), len(self.views), f"{name}.bufferView")]
        if not isinstance(view, dict):
            raise GltfError(f"{name}.bufferView is not an object")
        buffer = self.buffers[_index(view.get("buffer"), len(self.buffers), f"{name}.buffer")]
        item = np.dtype(dtype).itemsize * width
        stride = _int(view.get("byteStride", item), f"{name} byteStride") or item
        start = _int(view.get("byteOffset", 0), f"{name} view byteOffset") + _int(
            accessor.get("byteOffset", 0), f"{name}.byteOffset"
        )
        end = start + (stride * (count - 1) + item if count else 0)
        view_end = _int(view.get("byteOffset", 0), f"{name} view byteOffset") + _int(
            view.get("byteLength", 0), f"{name} view byteLength"
        )
        if start < 0 or stride < item or end > min(len(buffer), view_end):
            raise GltfError(f"{name}: {count} elements do not fit in bufferView {accessor.get('bufferView')}")
        rows = np.lib.stride_tricks.as_strided(
            np.frombuffer(buffer, dtype=np.uint8, count=max(end - start, 0), offset=start),
            shape=(count, item), strides=(stride, 1),
        ) if count else np.zeros((0, item), np.uint8)  # fmt: skip
        return np.ascontiguousarray(rows).view(dtype).reshape(count, width)


def _int(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**40:
        raise GltfError(f"{where}: {value!r} is not a byte count")
    return value


def _local_matrix(node: dict[str, Any], index: int) -> FloatArray:
    if "matrix" in node:
        values = node["matrix"]
        if not isinstance(values, list) or len(values) != 16:
            raise GltfError(f"nodes[{index}].matrix needs 16 numbers")
        matrix = _finite(values, f"nodes[{index}].matrix").reshape(4, 4).T  # column-major
        return matrix
    matrix = np.eye(4)
    if "scale" in node:
        matrix = np.diag([*_finite(node["scale"], f"nodes[{index}].scale", 3), 1.0])
    if "rotation" in node:
        x, y, z, w = _finite(node["rotation"], f"nodes[{index}].rotation", 4)
        rotation = np.eye(4)
        rotation[:3, :3] = rotation_matrix(np.array([w, x, y, z]))
        matrix = rotation @ matrix
    if "translation" in node:
        translation = np.eye(4)
        translation[:3, 3] = _finite(node["translation"], f"nodes[{index}].translation", 3)
        matrix = translation @ matrix
    return matrix


def _finite(values: Any, where: str, count: int | None = None) -> FloatArray:
    try:
        array = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise GltfError(f"{where} must be numbers") from None
    if (count is not None and array.size != count) or not np.isfinite(array).all():
        raise GltfError(f"{where} must be {count or 'some'} finite numbers")
    return array


def _mesh(
    document: dict[str, Any], reader: _Accessors, index: int, world: FloatArray, name: str
) -> list[GltfMesh]:
    mesh = _list(document, "meshes")[index]
    materials = _list(document, "materials")
    out = []
    for number, primitive in enumerate(_list(mesh, "primitives", f"meshes[{index}]")):
        where = f"meshes[{index}].primitives[{number}]"
        if not isinstance(primitive, dict) or primitive.get("mode", 4) != 4:
            raise GltfError(f"{where}: only triangles (mode 4) are rendered")
        attributes = primitive.get("attributes")
        if not isinstance(attributes, dict) or "POSITION" not in attributes:
            raise GltfError(f"{where} has no POSITION")
        positions = reader.read(attributes["POSITION"], f"{where}.POSITION").astype(np.float64)
        if positions.shape[1] != 3 or not np.isfinite(positions).all():
            raise GltfError(f"{where}.POSITION must be finite VEC3")
        if "indices" in primitive:
            indices = reader.read(primitive["indices"], f"{where}.indices").reshape(-1).astype(np.int64)
        else:
            indices = np.arange(len(positions))
        if indices.size % 3 or (indices.size and (indices.min() < 0 or indices.max() >= len(positions))):
            raise GltfError(f"{where}.indices: not triangles of existing vertices")
        color = (1.0, 1.0, 1.0, 1.0)
        if "material" in primitive:
            material = materials[_index(primitive["material"], len(materials), f"{where}.material")]
            factor = material.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])
            r, g, b, a = _finite(factor, f"{where} baseColorFactor", 4)
            color = (float(r), float(g), float(b), float(a))
        with np.errstate(over="ignore", invalid="ignore"):
            vertices = positions @ world[:3, :3].T + world[:3, 3]
        if vertices.size and not (np.isfinite(vertices).all() and np.abs(vertices).max() < 1e30):
            raise GltfError(f"{where}: vertices leave the range a renderer can hold")
        out.append(GltfMesh(vertices, indices.reshape(-1, 3).astype(np.uint32), color, name))
    return out


# --- writing ---------------------------------------------------------------------------------------


def _with_mesh(_: int, geometry: Geometry) -> tuple[Geometry, TriangleMesh]:
    return geometry, triangle_mesh(geometry.shape)


def write_gltf(scene: Scene, binary: bool = False) -> bytes:
    """A scene as a self-contained glTF 2.0 document (`.gltf` JSON, or `.glb` when `binary`).

    A geometry with no triangles to draw (a missing mesh file) is skipped (`viewer_bridge.model.skipped`)."""
    document: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "viewer-bridge"},
        "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [], "materials": [],
        "accessors": [], "bufferViews": [], "buffers": [],
    }  # fmt: skip
    blob = bytearray()
    for link in scene.links:
        link_pose = scene.link_pose(link)
        for geometry, mesh in per_geometry(link, _with_mesh):
            pose = link_pose.compose(geometry.pose)
            matrix = pose.matrix()
            positions = _add_accessor(document, blob, mesh.vertices.astype("<f4"), "VEC3", 5126, 34962)
            indices = _add_accessor(
                document, blob, mesh.triangles.astype("<u4").reshape(-1, 1), "SCALAR", 5125, 34963
            )
            material = {
                "baseColorFactor": list(geometry.color),
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0,
            }
            document["materials"].append({"pbrMetallicRoughness": material})
            document["meshes"].append({"primitives": [{"attributes": {"POSITION": positions}, "indices": indices,
                                                       "material": len(document["materials"]) - 1, "mode": 4}]})  # fmt: skip
            document["nodes"].append({"name": link.name, "mesh": len(document["meshes"]) - 1,
                                      "matrix": matrix.T.reshape(-1).tolist()})  # fmt: skip
            document["scenes"][0]["nodes"].append(len(document["nodes"]) - 1)
    if binary:
        document["buffers"] = [{"byteLength": len(blob)}]
        text = json.dumps(document, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        blob += b"\0" * (-len(blob) % 4)
        chunks = (
            struct.pack("<I4s", len(text), b"JSON")
            + text
            + struct.pack("<I4s", len(blob), b"BIN\0")
            + bytes(blob)
        )
        return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks
    uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode("ascii")
    document["buffers"] = [{"byteLength": len(blob), "uri": uri}]
    return json.dumps(document).encode()


def _add_accessor(document: dict[str, Any], blob: bytearray, values: np.ndarray[Any, Any], kind: str,
                  component: int, target: int) -> int:  # fmt: skip
    blob += b"\0" * (-len(blob) % 4)
    document["bufferViews"].append(
        {"buffer": 0, "byteOffset": len(blob), "byteLength": values.nbytes, "target": target}
    )
    accessor: dict[str, Any] = {"bufferView": len(document["bufferViews"]) - 1, "componentType": component,
                                "count": len(values), "type": kind}  # fmt: skip
    if kind == "VEC3" and len(values):
        accessor["min"], accessor["max"] = values.min(axis=0).tolist(), values.max(axis=0).tolist()
    document["accessors"].append(accessor)
    blob += values.tobytes()
    return len(document["accessors"]) - 1
