"""Rendering a glTF scene from a pinhole camera with OpenGL (moderngl): color, depth, label.

Headless through EGL (Mesa llvmpipe here, a GPU where EGL finds one). The projection is built
from the camera's intrinsics, not the glTF `yfov` (docs/PROTOCOLS.md section 5): P00 = 2fx/W,
P02 = (W - 2cx)/W, P11 = 2fy/H, P12 = -(H - 2cy)/H, rows flipped on readback.

* color: the material colour lit from the camera (normals from screen-space derivatives, since
  Drake's scenes carry none), on Drake's background (204, 229, 255);
* depth: eye-space z in metres (not ray length), drawn into a float target;
* label: the unlit baseColorFactor, no multisampling, white where nothing is.

A `Renderer` owns its GL context: use it from one thread. It keeps each mesh's GPU buffers
across requests, keyed by a hash of the bytes it would upload (`MeshCache`): Drake's client
sends the whole scene with every image, and a static mesh then costs no upload at all.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from viewer_bridge.formats.gltf import GltfScene
from viewer_bridge.model.scene import FloatArray
from viewer_bridge.util.extras import missing
from viewer_bridge.util.lru import SizedLru

try:
    import moderngl
except ImportError as error:
    raise missing(error, "rendering (snapshot, serve-render)") from None

BACKGROUND = (204 / 255, 229 / 255, 1.0)

_VERTEX = """
#version 330
uniform mat4 projection;
uniform mat4 view;
in vec3 position;
out vec3 eye;
void main() {
    vec4 at = view * vec4(position, 1.0);
    eye = at.xyz;
    gl_Position = projection * at;
}
"""

_FRAGMENT = """
#version 330
uniform vec4 base_color;
uniform int mode;  // 0 color, 1 depth, 2 label
in vec3 eye;
out vec4 result;
void main() {
    if (mode == 1) {
        result = vec4(-eye.z, 0.0, 0.0, 1.0);
    } else if (mode == 2) {
        result = base_color;
    } else {
        vec3 normal = normalize(cross(dFdx(eye), dFdy(eye)));
        float light = abs(dot(normal, normalize(-eye)));
        result = vec4(base_color.rgb * (0.35 + 0.65 * light), 1.0);
    }
}
"""


@dataclass(frozen=True)
class Camera:
    """Drake's CameraInfo and clipping range, and the camera's pose in the world (4 x 4)."""

    width: int
    height: int
    focal_x: float
    focal_y: float
    center_x: float
    center_y: float
    near: float
    far: float
    pose: FloatArray

    def projection(self) -> FloatArray:
        w, h, n, f = self.width, self.height, self.near, self.far
        matrix = np.zeros((4, 4))
        matrix[0, 0] = 2 * self.focal_x / w
        matrix[0, 2] = (w - 2 * self.center_x) / w
        matrix[1, 1] = 2 * self.focal_y / h
        matrix[1, 2] = -(h - 2 * self.center_y) / h
        matrix[2, 2] = -(f + n) / (f - n)
        matrix[2, 3] = -2 * f * n / (f - n)
        matrix[3, 2] = -1.0
        return matrix


# Enough for a few million triangles of static scenery; llvmpipe keeps buffers in host memory.
DEFAULT_CACHE_BYTES = 256 * 1024 * 1024


@dataclass
class _GpuMesh:
    vertices: Any  # moderngl.Buffer
    indices: Any  # moderngl.Buffer
    array: Any  # moderngl.VertexArray
    size: int  # bytes held on the GPU

    def release(self) -> None:
        self.array.release()
        self.vertices.release()
        self.indices.release()


class MeshCache:
    """GPU buffers by content: a blake2b of the vertex and index bytes -> buffers and vertex array.

    Least recently used entries are released once the total exceeds `max_bytes`. Keyed by the
    very bytes uploaded, so a hit draws exactly what an upload would have.
    """

    def __init__(self, context: Any, program: Any, max_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        self.context, self.program = context, program
        # The newest mesh stays even when it alone is larger: the request drawing it needs it.
        self.entries: SizedLru[bytes, _GpuMesh] = SizedLru(max_bytes, keep_newest=True)
        self.hits = self.misses = 0

    def vertex_array(self, vertices: bytes, indices: bytes) -> Any:
        key = hashlib.blake2b(vertices, digest_size=16)
        key.update(indices)  # a separate buffer: same digest as hashing their concatenation
        digest = key.digest() + len(vertices).to_bytes(8, "little")
        entry = self.entries.get(digest)
        if entry is not None:
            self.hits += 1
            return entry.array
        self.misses += 1
        entry = self._upload(vertices, indices)
        for evicted in self.entries.put(digest, entry, entry.size):
            evicted.release()
        return entry.array

    def _upload(self, vertices: bytes, indices: bytes) -> _GpuMesh:
        vertex_buffer = self.context.buffer(vertices)
        index_buffer = self.context.buffer(indices)
        array = self.context.vertex_array(
            self.program, [(vertex_buffer, "3f", "position")], index_buffer=index_buffer
        )
        return _GpuMesh(vertex_buffer, index_buffer, array, len(vertices) + len(indices))


class Renderer:
    """Renders `GltfScene`s; one GL context, one program, mesh buffers cached by content."""

    def __init__(self, cache_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        self.context = moderngl.create_standalone_context(backend="egl")  # type: ignore[arg-type]
        self.program = self.context.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)
        self.uniforms: dict[str, Any] = {
            name: self.program[name] for name in ("projection", "view", "mode", "base_color")
        }
        self.meshes = MeshCache(self.context, self.program, cache_bytes)

    def render(self, scene: GltfScene, camera: Camera, kind: str) -> np.ndarray[Any, Any]:
        """An H x W x 4 float32 image, top row first: colour in [0, 1], depth in metres (inf: no
        hit), or label colours in [0, 1] (white: no hit)."""
        # Made current first: the cached buffers' ids mean nothing in another renderer's context.
        with self.context:
            return self._render(scene, camera, kind)

    def _render(self, scene: GltfScene, camera: Camera, kind: str) -> np.ndarray[Any, Any]:
        ctx = self.context
        target = ctx.texture((camera.width, camera.height), 4, dtype="f4")
        depth = ctx.depth_renderbuffer((camera.width, camera.height))
        framebuffer = ctx.framebuffer(color_attachments=[target], depth_attachment=depth)
        try:
            framebuffer.use()
            ctx.viewport = (0, 0, camera.width, camera.height)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
            background = {
                "color": (*BACKGROUND, 1.0),
                "depth": (-1.0, 0.0, 0.0, 1.0),
                "label": (1.0, 1.0, 1.0, 1.0),
            }[kind]
            framebuffer.clear(*background, depth=1.0)
            self.uniforms["projection"].write(camera.projection().T.astype("f4").tobytes())
            self.uniforms["view"].write(np.linalg.inv(camera.pose).T.astype("f4").tobytes())
            self.uniforms["mode"].value = {"color": 0, "depth": 1, "label": 2}[kind]
            for mesh in scene.meshes:
                if not len(mesh.triangles):
                    continue
                self.uniforms["base_color"].value = tuple(float(c) for c in mesh.color)
                array = self.meshes.vertex_array(
                    mesh.vertices.astype("f4").tobytes(), mesh.triangles.astype("u4").tobytes()
                )
                array.render(moderngl.TRIANGLES)
            pixels = np.frombuffer(framebuffer.read(components=4, dtype="f4"), dtype=np.float32)
        finally:
            framebuffer.release()
            target.release()
            depth.release()
        image = pixels.reshape(camera.height, camera.width, 4)[::-1].copy()
        if kind == "depth":
            image[..., 0][image[..., 0] < 0] = np.inf  # the cleared background: nothing there
        return image


def rgb8(image: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """A color or label render as 8-bit RGB (labels: each channel rounded once, so exact)."""
    return np.clip(np.round(image[..., :3] * 255), 0, 255).astype(np.uint8)


def depth_mm(image: np.ndarray[Any, Any], min_depth: float, max_depth: float) -> np.ndarray[Any, Any]:
    """16-bit millimetres: 0 nearer than min_depth, 65535 beyond max_depth or where nothing is."""
    z = image[..., 0].astype(np.float64)
    out = np.full(z.shape, 65535, dtype=np.uint16)
    near = z < min_depth
    inside = ~near & (z <= max_depth) & np.isfinite(z)
    out[near] = 0
    out[inside] = np.clip(np.round(z[inside] * 1000.0), 0, 65534).astype(np.uint16)
    return out
