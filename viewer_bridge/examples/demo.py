"""A moving, Drake-like scene with every shape, for trying the bridge with no simulator."""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path

import numpy as np

from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.model.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    FileContents,
    Geometry,
    HalfSpace,
    InMemoryMesh,
    Link,
    LinkPoses,
    MeshFile,
    Pose,
    Scene,
    Shape,
    Sphere,
    TriangleMesh,
)
from viewer_bridge.transports.lcm import Publisher

# Inside the package (and the wheel), so that a recording of the demo still finds its mesh file.
DEMO_MESH = Path(__file__).resolve().parent / "demo_data" / "tetrahedron.obj"
TETRAHEDRON_OBJ = DEMO_MESH.read_text()


def demo_scene() -> Scene:
    """One model instance with a link per shape, plus a ground half-space on `world`."""
    vertices = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]], dtype=np.float64)
    triangles = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    shapes: list[Shape] = [
        Box((0.2, 0.1, 0.05)),
        Sphere(0.05),
        Cylinder(0.03, 0.2),
        Capsule(0.03, 0.1),
        Ellipsoid((0.05, 0.08, 0.03)),
        MeshFile(str(DEMO_MESH), (1.0, 1.0, 1.0)),
        TriangleMesh(vertices, triangles),
        InMemoryMesh(FileContents(TETRAHEDRON_OBJ.encode(), ".obj", "tetrahedron.obj")),
    ]
    links = [Link("world", 0, (Geometry(HalfSpace(), Pose(), (0.6, 0.6, 0.6, 1.0)),))]
    for index, shape in enumerate(shapes):
        hue = index / len(shapes)
        color = (
            0.5 + 0.5 * math.cos(6.28 * hue),
            0.5 + 0.5 * math.cos(6.28 * (hue - 0.33)),
            0.5 + 0.5 * math.cos(6.28 * (hue - 0.66)),
            1.0,
        )
        name = f"demo::shapes::{type(shape).__name__.lower()}_{index}"
        links.append(Link(name, 1, (Geometry(shape, Pose(), color),)))
    return Scene(tuple(links))


def demo_poses(scene: Scene, seconds: float) -> LinkPoses:
    """Links on a slowly turning circle, each spinning about z."""
    moving = [link for link in scene.links if link.name != "world"]
    count = len(moving)
    angles = seconds * 0.5 + np.arange(count) * (2 * math.pi / count)
    positions = np.stack([0.5 * np.cos(angles), 0.5 * np.sin(angles), np.full(count, 0.3)], axis=1)
    spin = seconds * 1.0 + np.arange(count)
    quaternions = np.stack([np.cos(spin / 2), np.zeros(count), np.zeros(count), np.sin(spin / 2)], axis=1)
    return LinkPoses(
        timestamp_ms=int(seconds * 1000),
        names=tuple(link.name for link in moving),
        robot_nums=np.array([link.robot_num for link in moving], dtype=np.int32),
        positions=positions,
        quaternions_wxyz=quaternions,
    )


def run_demo(
    url: str,
    duration: float | None,
    rate_hz: float = 60.0,
    stop: threading.Event | None = None,
    load_every: float = 2.0,
) -> int:
    """Publish the demo's load (again every `load_every` s, for late listeners) and draws."""
    stop = stop or threading.Event()
    publisher = Publisher(url)
    encoder = DrawEncoder()
    sent = 0
    scene = demo_scene()
    load = load_from_scene(scene).encode()
    start = time.monotonic()
    next_load = start
    while not stop.is_set():
        now = time.monotonic()
        if duration is not None and now - start >= duration:
            break
        if now >= next_load:
            publisher.publish("DRAKE_VIEWER_LOAD_ROBOT", load)
            next_load = now + load_every
        publisher.publish("DRAKE_VIEWER_DRAW", encoder.encode(demo_poses(scene, now - start)))
        sent += 1
        stop.wait(1.0 / rate_hz)
    return sent


__all__ = [
    "DEMO_MESH",
    "TETRAHEDRON_OBJ",
    "demo_poses",
    "demo_scene",
    "run_demo",
]
