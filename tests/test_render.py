"""The glTF render server against Drake itself: its RenderEngineGltfClient, and RenderEngineVtk."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytestmark = pytest.mark.slow

OBJ_WITH_NORMALS = """\
v 0 0 0
v 0.2 0 0
v 0 0.2 0
v 0 0 0.2
vn -0.577 -0.577 -0.577
vn 0.577 0.577 0.577
f 1//1 3//1 2//1
f 1//1 2//1 4//1
f 1//1 4//1 3//1
f 2//2 3//2 4//2
"""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@pytest.fixture(scope="module")
def render_url() -> Iterator[str]:
    port = free_port()
    server = subprocess.Popen([sys.executable, "-m", "bridge.cli", "serve-render", "--port", str(port)],
                              stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            break
        except OSError:
            time.sleep(0.1)
    yield f"http://127.0.0.1:{port}"
    server.terminate()
    server.wait(timeout=10)


def drake_images(url: str, folder: Path, width: int = 160, height: int = 120) -> dict[str, dict[str, Any]]:
    """Every shape, seen by one camera through our server ("gltf") and through Drake's VTK."""
    import pydrake.all as drake

    obj = folder / "tetra.obj"
    obj.write_text(OBJ_WITH_NORMALS)
    builder = drake.DiagramBuilder()
    plant, scene_graph = drake.AddMultibodyPlantSceneGraph(builder, 0.0)
    scene_graph.AddRenderer(
        "gltf", drake.MakeRenderEngineGltfClient(drake.RenderEngineGltfClientParams(base_url=url))
    )
    scene_graph.AddRenderer("vtk", drake.MakeRenderEngineVtk(drake.RenderEngineVtkParams()))
    shapes = [drake.Box(0.2, 0.3, 0.1), drake.Sphere(0.1), drake.Cylinder(0.08, 0.25), drake.Capsule(0.06, 0.2),
              drake.Ellipsoid(0.1, 0.15, 0.08),
              drake.Mesh(str(obj), 1.5)]  # fmt: skip
    for index, shape in enumerate(shapes):
        body = plant.AddRigidBody(f"body{index}", drake.SpatialInertia.SolidSphereWithMass(1.0, 0.1))
        pose = drake.RigidTransform(
            drake.RollPitchYaw(0.3 * index, 0.2, 0.1),
            [(index % 3 - 1) * 0.35, (index // 3) * 0.4 - 0.2, 0.15],
        )
        plant.RegisterVisualGeometry(
            body, pose, shape, f"v{index}", [0.2 + 0.1 * index, 0.5, 0.8 - 0.1 * index, 1.0]
        )
    plant.RegisterVisualGeometry(
        plant.world_body(), drake.RigidTransform(), drake.HalfSpace(), "ground", [0.5, 0.5, 0.5, 1.0]
    )
    plant.Finalize()
    camera_pose = drake.RigidTransform(drake.RollPitchYaw(-2.3, 0.0, 0.0), [0.0, -1.2, 1.2])
    sensors = {}
    for renderer in ("gltf", "vtk"):
        core = drake.RenderCameraCore(
            renderer,
            drake.CameraInfo(width, height, np.pi / 3),
            drake.ClippingRange(0.05, 10.0),
            drake.RigidTransform(),
        )
        sensor = drake.RgbdSensor(scene_graph.world_frame_id(), camera_pose, drake.ColorRenderCamera(core, False),
                            drake.DepthRenderCamera(core, drake.DepthRange(0.1, 5.0)))  # fmt: skip
        sensors[renderer] = builder.AddSystem(sensor)
        builder.Connect(scene_graph.get_query_output_port(), sensors[renderer].query_object_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    images: dict[str, dict[str, Any]] = {}
    for renderer, sensor in sensors.items():
        sensor_context = sensor.GetMyContextFromRoot(context)
        images[renderer] = {
            port: np.array(sensor.GetOutputPort(port).Eval(sensor_context).data, copy=True)
            for port in ("color_image", "depth_image_32f", "label_image")
        }
    return images


def test_drake_renders_through_the_server_like_its_own_vtk(render_url: str, tmp_path: Path) -> None:
    images = drake_images(render_url, tmp_path)
    ours, vtk = images["gltf"], images["vtk"]
    labels_ours, labels_vtk = ours["label_image"][..., 0], vtk["label_image"][..., 0]
    assert len(np.unique(labels_vtk)) >= 7  # every body, the ground, and the sky are in view
    mismatch = labels_ours != labels_vtk
    print(f"label pixels that differ: {int(mismatch.sum())} of {mismatch.size}")
    depth_ours, depth_vtk = ours["depth_image_32f"][..., 0], vtk["depth_image_32f"][..., 0]
    both = np.isfinite(depth_ours) & np.isfinite(depth_vtk)
    difference = np.abs(depth_ours[both] - depth_vtk[both])
    print(f"depth: max difference {difference.max() * 1000:.3f} mm over {int(both.sum())} pixels")
    color_difference = np.abs(
        ours["color_image"][..., :3].astype(int) - vtk["color_image"][..., :3].astype(int)
    )
    print(f"color: mean absolute difference {color_difference.mean():.1f} of 255")
    assert (np.isfinite(depth_ours) == np.isfinite(depth_vtk)).mean() > 0.999
    assert not mismatch.any()
    assert difference.max() <= 0.001
