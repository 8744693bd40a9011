"""Benchmark: the glTF render server's time per 640x480 image beside Drake's RenderEngineVtk.

Run: .venv/bin/python bench/render.py [--quick]

One pydrake diagram with two renderers on the same scene and camera: "gltf" is
RenderEngineGltfClient pointed at `viewer-bridge serve-render` (a process of its own, which logs
its server-side time per request: parse, render, PNG), "vtk" is RenderEngineVtk (EGL). Two
scenes: every Drake shape with a ground plane, and the same plus a 100,000-triangle mesh.
VTK's time is Drake's own evaluation of the sensor port (render and readback). Goals: the
small scene within 1.2x VTK, the 100,000-triangle one within 1.5x (meshes are cached by content).
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
from common import Measure, Size  # bench/ is on sys.path when run as a script


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


def wait_for(port: int, seconds: float = 30.0) -> None:
    """Until the server accepts connections (it starts slower on a busy machine)."""
    deadline = time.monotonic() + seconds
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            return
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


# Goals (issue 15, goal 7): server-side time within this factor of RenderEngineVtk's.
GOALS = {False: 1.2, True: 1.5}


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Median server-side ms per image (ours) beside RenderEngineVtk (baseline), per scene and kind."""
    repeats = size.pick(full=5, quick=3, smoke=1)
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "viewer_bridge.cli.main", "serve-render", "--port", str(port)],
                              stderr=subprocess.PIPE, text=True)  # fmt: skip
    lines: list[str] = []
    assert server.stderr is not None
    threading.Thread(target=lambda: lines.extend(server.stderr), daemon=True).start()  # type: ignore[arg-type]
    wait_for(port)
    ports = {"color": "color_image", "depth": "depth_image_32f", "label": "label_image"}
    rows: list[Measure] = []
    try:
        with tempfile.TemporaryDirectory() as folder:
            for label, big in (("every shape + ground", False), ("+ 100,000-triangle mesh", True)):
                diagram, sensors = build(f"http://127.0.0.1:{port}", Path(folder), big)
                for kind, port_name in ports.items():
                    times: dict[str, list[float]] = {"gltf": [], "vtk": []}
                    for _ in range(repeats):
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
                    ours = float(np.median(served)) if served else float("nan")
                    vtk = float(np.median(times["vtk"])) * 1e3
                    goal = GOALS[big]
                    rows.append(Measure(f"render {kind}, {label}", ours, vtk, "ms",
                                        f"<= {goal}x RenderEngineVtk", ours <= goal * vtk))  # fmt: skip
    finally:
        server.terminate()
        server.wait()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="3 repeats instead of 5")
    args = parser.parse_args()
    print(f"{'scene, image':<42} | {'serve-render':>12} | {'RenderEngineVtk':>15} | {'ratio':>6} | goal")
    for row in measures(Size.QUICK if args.quick else Size.FULL):
        assert row.baseline is not None
        print(f"{row.name:<42} | {row.ours:>9.1f} ms | {row.baseline:>12.1f} ms | "
              f"{row.ours / row.baseline:>5.2f}x | {row.goal}: {'met' if row.met else 'NOT met'}")  # fmt: skip


if __name__ == "__main__":
    main()
