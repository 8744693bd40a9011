"""`viewer-bridge snapshot`: the current scene of a log or a live LCM bus, rendered to a PNG or JPEG.

The scene is the last load of the chosen role with the last draw applied; it goes through the
same path as a render request (scene -> glTF -> renderer), so what a user sees is what a glTF
render server would draw. The default camera looks at the scene's middle from above and aside.

With contacts (`--contacts`), the last `CONTACT_RESULTS` is drawn over the scene as meldis draws
it: `viewer_bridge.model.contact.contact_scene`'s arrows as solid arrows, each hydroelastic surface in bands of
its pressure colours (the renderer colours whole meshes, so triangles are grouped by the colour
of their mean pressure). `--hide REGEX` leaves out the links whose names match, e.g. the body
that covers a contact surface.
"""

from __future__ import annotations

import io
import math
import re
from pathlib import Path

import numpy as np
from PIL import Image

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.drake.draw import DrawDecoder
from viewer_bridge.formats.drake.load import decode_load
from viewer_bridge.formats.gltf import read_gltf, write_gltf
from viewer_bridge.lcmcodec.codecs import CONTACT_RESULTS, DRAW, LOAD_ROBOT
from viewer_bridge.model.contact import ContactDrawOptions, ContactResults, contact_scene, pressure_colors
from viewer_bridge.model.lowering import arrow_mesh
from viewer_bridge.model.scene import FloatArray, Geometry, Line, Link, Scene, TriangleMesh
from viewer_bridge.render.renderer import Camera, Renderer, depth_mm, rgb8
from viewer_bridge.transports.lcm import LcmEvent, Subscription, read_log


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
        loads = sorted({e.channel for e in events if e.channel.startswith("DRAKE_VIEWER_LOAD_ROBOT")})
        raise SceneError(
            f"no DRAKE_VIEWER_LOAD_ROBOT{suffix} message in the source"
            + (f" (it has {', '.join(loads)}: choose with --role)" if loads else "")
        )
    scene = decode_load(load)
    return scene.with_poses(DrawDecoder().decode(draw)) if draw is not None else scene


def latest_contacts(events: list[LcmEvent]) -> ContactResults | None:
    """The last `CONTACT_RESULTS` message of the source, or None when it has none."""
    data = None
    for event in events:
        if event.channel == "CONTACT_RESULTS" and event.data[:8] == CONTACT_RESULTS.packed_fingerprint:
            data = event.data
    return None if data is None else decode_contact_results(data)


def without_links(scene: Scene, pattern: str) -> Scene:
    """The scene less the links whose names match the regular expression `pattern` (searched)."""
    matcher = re.compile(pattern)
    return Scene(tuple(link for link in scene.links if not matcher.search(link.name)), scene.poses)


def with_contacts(scene: Scene, results: ContactResults, options: ContactDrawOptions | None = None) -> Scene:
    """The scene with its contacts drawn in the world frame, in shapes the renderer draws."""
    contacts = contact_scene(results, options)
    links = tuple(
        Link(link.name, link.robot_num, tuple(part for g in link.geometries for part in _renderable(g)))
        for link in contacts.links
    )
    return Scene(scene.links + links, scene.poses)


_BANDS = 16  # colours a pressure-coloured surface is drawn in
_SURFACE_LIFT = np.array([0.0, 0.0, 0.001])


def _renderable(geometry: Geometry) -> list[Geometry]:
    shape = geometry.shape
    if isinstance(shape, Line):
        return [Geometry(arrow_mesh(shape), geometry.pose, geometry.color)]
    if isinstance(shape, TriangleMesh) and shape.colors is not None:
        # Contact surfaces lie in the face of the body they press on: drawn 1 mm above it (the
        # cameras here look from above), so the renderer's depth test does not mix the two.
        lifted = TriangleMesh(shape.vertices + _SURFACE_LIFT, shape.triangles, shape.colors)
        return _colour_bands(lifted, geometry)
    return [geometry]


def _colour_bands(mesh: TriangleMesh, geometry: Geometry) -> list[Geometry]:
    """A vertex-coloured mesh as up to `_BANDS` single-coloured meshes, a triangle in the band of
    its mean colour's position on the ramp."""
    assert mesh.colors is not None
    ramp = pressure_colors(np.linspace(0.0, 1.0, _BANDS), 0.0, 1.0)
    face_colors = mesh.colors[mesh.triangles].mean(axis=1)
    band = np.argmin(np.linalg.norm(face_colors[:, None, :] - ramp[None, :, :], axis=2), axis=1)
    parts = []
    for index in np.unique(band):
        r, g, b = (float(value) for value in ramp[index])
        part = TriangleMesh(mesh.vertices, mesh.triangles[band == index])
        parts.append(Geometry(part, geometry.pose, (r, g, b, 1.0)))
    return parts


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
    file_format: str = "PNG",
) -> bytes:
    """The scene as an image file's bytes: color, label or 16-bit millimetre depth, as a PNG (or
    in another format Pillow writes, e.g. JPEG for color and label)."""
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
    picture.save(out, format=file_format)
    return out.getvalue()


def events_from(source: str, duration: float) -> list[LcmEvent]:
    """A log file's events, or what a live LCM URL carries for `duration` seconds."""
    if Path(source).is_file():
        return list(read_log(source))
    return list(Subscription(source).events(duration))
