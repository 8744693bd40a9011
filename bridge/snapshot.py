"""`viewer-bridge snapshot`: the current scene of a log or a live LCM bus, rendered to a PNG.

The scene is the last load of the chosen role with the last draw applied; it goes through the
same path as a render request (scene -> glTF -> renderer), so what a user sees is what a glTF
render server would draw. The default camera looks at the scene's middle from above and aside.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
from PIL import Image

from bridge.formats.drake import DrawDecoder, decode_load
from bridge.formats.gltf import read_gltf, write_gltf
from bridge.lcmcodec import DRAW, LOAD_ROBOT
from bridge.render import Camera, Renderer, depth_mm, rgb8
from bridge.scene import FloatArray, Scene
from bridge.transports.lcm import LcmEvent, Subscription, read_log


def latest_scene(events: list[LcmEvent], role: str = "") -> Scene:
    """The last load of `role` ("" for unsuffixed channels, else e.g. "ILLUSTRATION") posed by its last draw."""
    suffix = f"_{role}" if role else ""
    load = draw = None
    for event in events:
        if (
            event.channel == f"DRAKE_VIEWER_LOAD_ROBOT{suffix}"
            and event.data[:8] == LOAD_ROBOT.packed_fingerprint
        ):
            load = event.data
        elif event.channel == f"DRAKE_VIEWER_DRAW{suffix}" and event.data[:8] == DRAW.packed_fingerprint:
            draw = event.data
    if load is None:
        raise ValueError(f"no DRAKE_VIEWER_LOAD_ROBOT{suffix} message in the source")
    scene = decode_load(load)
    return scene.with_poses(DrawDecoder().decode(draw)) if draw is not None else scene


def look_at(eye: FloatArray, target: FloatArray) -> FloatArray:
    """A camera pose (OpenGL: looking down -Z, +Y up) at `eye` looking at `target`, world z up."""
    forward = target - eye
    forward = forward / np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, true_up, -forward, eye
    return pose


def default_camera(points: FloatArray, fov_y: float) -> tuple[FloatArray, FloatArray]:
    """Eye and target framing `points` (vertices of the scene, big ground planes left out)."""
    low, high = np.percentile(points, 2, axis=0), np.percentile(points, 98, axis=0)
    target = (low + high) / 2
    radius = max(float(np.linalg.norm(high - low)) / 2, 0.1)
    distance = radius / math.tan(fov_y / 2) * 1.2
    direction = np.array([1.0, -1.2, 1.0]) / np.linalg.norm([1.0, -1.2, 1.0])
    return target + direction * distance, target


def snapshot(
    scene: Scene,
    width: int = 640,
    height: int = 480,
    fov_y_deg: float = 45.0,
    eye: FloatArray | None = None,
    target: FloatArray | None = None,
    image: str = "color",
) -> bytes:
    """PNG bytes of the scene (color, label or 16-bit millimetre depth)."""
    gltf = read_gltf(write_gltf(scene))
    fov_y = math.radians(fov_y_deg)
    if eye is None or target is None:
        small = [mesh.vertices for mesh in gltf.meshes if np.ptp(mesh.vertices, axis=0).max() < 20]
        points = np.concatenate(small or [mesh.vertices for mesh in gltf.meshes] or [np.zeros((1, 3))])
        eye, target = default_camera(points, fov_y)
    focal = height / 2 / math.tan(fov_y / 2)
    camera = Camera(width, height, focal, focal, width / 2, height / 2, 0.01, 100.0, look_at(eye, target))
    pixels = Renderer().render(gltf, camera, image)
    depth = image == "depth"
    picture = (
        Image.fromarray(depth_mm(pixels, 0.01, 100.0)) if depth else Image.fromarray(rgb8(pixels), "RGB")
    )
    out = io.BytesIO()
    picture.save(out, format="PNG")
    return out.getvalue()


def events_from(source: str, duration: float) -> list[LcmEvent]:
    """A log file's events, or what a live LCM URL carries for `duration` seconds."""
    if Path(source).is_file():
        return list(read_log(source))
    return list(Subscription(source).events(duration))
