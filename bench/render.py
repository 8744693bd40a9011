"""Benchmark: the glTF render server's time per 640x480 image beside Drake's RenderEngineVtk.

Run: .venv/bin/python bench/render.py [--repeats 5]

One pydrake diagram with two renderers on the same scene and camera: "gltf" is
RenderEngineGltfClient pointed at `viewer-bridge serve-render` (a process of its own, which logs
its server-side time per request: parse, render, PNG), "vtk" is RenderEngineVtk (EGL). Two
scenes: every Drake shape with a ground plane, and the same plus a 100,000-triangle mesh.
VTK's time is Drake's own evaluation of the sensor port (render and readback).
"""

from __future__ import annotations

import argparse
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pydrake.all as drake
import trimesh


def build(url: str, folder: Path, big: bool) -> tuple[object, dict[str, object]]:
    builder = drake.DiagramBuilder()
    plant, scene_graph = drake.AddMultibodyPlantSceneGraph(builder, 0.0)
    scene_graph.AddRenderer(
        "gltf", drake.MakeRenderEngineGltfClient(drake.RenderEngineGltfClientParams(base_url=url))
    )
    scene_graph.AddRenderer("vtk", drake.MakeRenderEngineVtk(drake.RenderEngineVtkParams()))
    shapes = [drake.Box(0.2, 0.3, 0.1), drake.Sphere(0.1), drake.Cylinder(0.08, 0.25), drake.Capsule(0.06, 0.2),
              drake.Ellipsoid(0.1, 0.15, 0.08)]  # fmt: skip
    if big:
        mesh = trimesh.util.concatenate(
            [trimesh.creation.icosphere(6, 0.3), trimesh.creation.icosphere(5, 0.2)]
        )
        path = folder / "big.obj"
        path.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=True))
        shapes.append(drake.Mesh(str(path)))
    for index, shape in enumerate(shapes):
        body = plant.AddRigidBody(f"body{index}", drake.SpatialInertia.SolidSphereWithMass(1.0, 0.1))
        pose = drake.RigidTransform(
            drake.RollPitchYaw(0.3 * index, 0.2, 0.1), [(index % 3 - 1) * 0.35, (index // 3) * 0.4, 0.15]
        )
        plant.RegisterVisualGeometry(
            body, pose, shape, f"v{index}", [0.2 + 0.1 * index, 0.5, 0.8 - 0.1 * index, 1.0]
        )
    plant.RegisterVisualGeometry(
        plant.world_body(), drake.RigidTransform(), drake.HalfSpace(), "ground", [0.5] * 3 + [1.0]
    )
    plant.Finalize()
    sensors = {}
    for renderer in ("gltf", "vtk"):
        core = drake.RenderCameraCore(renderer, drake.CameraInfo(640, 480, np.pi / 3), drake.ClippingRange(0.05, 10.0),
                                      drake.RigidTransform())  # fmt: skip
        camera_pose = drake.RigidTransform(drake.RollPitchYaw(-2.3, 0, 0), [0, -1.2, 1.2])
        depth = drake.DepthRenderCamera(core, drake.DepthRange(0.1, 5.0))
        sensor = drake.RgbdSensor(
            scene_graph.world_frame_id(), camera_pose, drake.ColorRenderCamera(core, False), depth
        )
        sensors[renderer] = builder.AddSystem(sensor)
        builder.Connect(scene_graph.get_query_output_port(), sensors[renderer].query_object_input_port())
    return builder.Build(), sensors


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "bridge.cli", "serve-render", "--port", str(port)],
                              stderr=subprocess.PIPE, text=True)  # fmt: skip
    lines: list[str] = []
    assert server.stderr is not None
    threading.Thread(target=lambda: lines.extend(server.stderr), daemon=True).start()  # type: ignore[arg-type]
    time.sleep(2.0)
    ports = {"color": "color_image", "depth": "depth_image_32f", "label": "label_image"}
    print(f"{'scene':<28} {'image':<6} | {'serve-render (server side)':>26} | {'RenderEngineVtk':>16}")
    with tempfile.TemporaryDirectory() as folder:
        for label, big in (("every shape + ground", False), ("+ 100,000-triangle mesh", True)):
            diagram, sensors = build(f"http://127.0.0.1:{port}", Path(folder), big)
            for kind, port_name in ports.items():
                times = {"gltf": [], "vtk": []}
                for _ in range(args.repeats):
                    for renderer, sensor in sensors.items():
                        context = diagram.CreateDefaultContext()  # type: ignore[attr-defined]
                        sensor_context = sensor.GetMyContextFromRoot(context)  # type: ignore[attr-defined]
                        begun = time.perf_counter()
                        sensor.GetOutputPort(port_name).Eval(sensor_context)  # type: ignore[attr-defined]
                        times[renderer].append(time.perf_counter() - begun)
                time.sleep(0.2)
                served = [
                    float(m.group(1))
                    for line in lines
                    if (m := re.search(rf"rendered {kind} 640x480 in ([0-9.]+) ms", line))
                ]
                lines.clear()
                ours = np.median(served) if served else float("nan")
                vtk = np.median(times["vtk"]) * 1e3
                print(f"{label:<28} {kind:<6} | {ours:>23.1f} ms | {vtk:>13.1f} ms")
    server.terminate()
    server.wait()


if __name__ == "__main__":
    main()
