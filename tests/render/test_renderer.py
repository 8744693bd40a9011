"""The glTF render server against Drake itself: its RenderEngineGltfClient, and RenderEngineVtk."""

from __future__ import annotations

import io
import json
import random
import re
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

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


def start_server(*args: str) -> tuple[subprocess.Popen[str], str]:
    """`viewer-bridge serve-render` on a free port, once it says it is ready, and the base URL it
    prints: the one Drake's RenderEngineGltfClientParams takes (every test here renders through it)."""
    server = subprocess.Popen([sys.executable, "-m", "viewer_bridge.cli.main", "serve-render", "--port", "0", *args],
                              stderr=subprocess.PIPE, text=True)  # fmt: skip
    assert server.stderr is not None
    logged = []
    for line in server.stderr:  # the server's first lines, until it is ready (or gone)
        logged.append(line)
        if ready := re.search(
            r"render server on (\S+) \(Drake: RenderEngineGltfClientParams\(base_url=\"(.*?)\"\)", line
        ):
            break
    assert ready is not None and ready.group(1) == ready.group(2), logged
    threading.Thread(target=server.stderr.read, daemon=True).start()  # keep its pipe from filling
    return server, ready.group(1)


@pytest.fixture(scope="module")
def render_url() -> Iterator[str]:
    server, url = start_server()
    yield url
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


# --- bad requests, fuzzing ------------------------------------------------------------------------------


def form(scene: bytes, **overrides: Any) -> dict[str, bytes]:
    import hashlib

    fields = {"scene": scene, "scene_sha256": hashlib.sha256(scene).hexdigest().encode(), "image_type": b"label",
              "width": b"16", "height": b"12", "near": b"0.01", "far": b"10", "focal_x": b"14", "focal_y": b"14",
              "center_x": b"7.5", "center_y": b"5.5", "min_depth": b"0.1", "max_depth": b"5"}  # fmt: skip
    fields.update({key: value for key, value in overrides.items() if value is not None})
    for key in [key for key, value in overrides.items() if value is None]:
        fields.pop(key)
    return fields


def sample_gltf() -> bytes:
    from viewer_bridge.formats.gltf import write_gltf
    from viewer_bridge.model.scene import Box, Geometry, Link, Pose, Scene

    scene = Scene((Link("box", 0, (Geometry(Box((1.0, 1.0, 1.0)), Pose((0, 0, -3)), (1 / 255, 0, 0, 1)),)),))
    document = json.loads(write_gltf(scene))
    document["cameras"] = [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.01, "zfar": 10}}]
    document["nodes"].append({"camera": 0, "matrix": np.eye(4).reshape(-1).tolist()})
    document["scenes"][0]["nodes"].append(len(document["nodes"]) - 1)
    return json.dumps(document).encode()


@pytest.fixture(scope="module")
def renderer() -> Any:
    from viewer_bridge.render.server import RenderThread

    return RenderThread()


def test_a_good_request_renders_the_label(renderer: Any) -> None:
    from PIL import Image

    from viewer_bridge.render.server import render_request

    png = render_request(form(sample_gltf()), renderer.render)
    pixels = np.array(Image.open(io.BytesIO(png)))
    assert pixels.shape == (12, 16, 3)
    assert tuple(pixels[6, 8]) == (1, 0, 0) and tuple(pixels[0, 0]) == (255, 255, 255)  # the box; nothing


@pytest.mark.parametrize(
    ("overrides", "reason"),
    [
        ({"scene_sha256": b"0" * 64}, "scene_sha256 does not match"),
        ({"width": None}, "missing form field 'width'"),
        ({"height": b"twelve"}, "height is not a number"),
        ({"image_type": b"normals"}, "unsupported image_type 'normals'"),
        ({"image_type": b"depth", "max_depth": None}, "missing form field 'max_depth'"),
        ({"width": b"1e9"}, r"at most 4096x4096 \(the server's limit.*asked for 1e9x"),
        ({"near": b"20"}, "0 < near < far"),
    ],
)
def test_bad_forms_get_a_400_reason(renderer: Any, overrides: dict[str, Any], reason: str) -> None:
    from viewer_bridge.render.server import BadRequest, render_request

    with pytest.raises(BadRequest, match=reason):
        render_request(form(sample_gltf(), **overrides), renderer.render)


def mutate(document: dict[str, Any], rng: random.Random) -> dict[str, Any]:
    """One random, mostly plausible damage to a glTF document."""
    document = json.loads(json.dumps(document))
    odd = rng.choice([-1, 2**31, 2**62, 1e300, None, "x", [], {}, 0, 3, True])
    target = rng.choice(["accessor", "view", "buffer", "node", "mesh", "material", "drop"])
    if target == "accessor":
        rng.choice(document["accessors"])[
            rng.choice(["count", "componentType", "type", "byteOffset", "bufferView"])
        ] = odd
    elif target == "view":
        rng.choice(document["bufferViews"])[
            rng.choice(["byteOffset", "byteLength", "byteStride", "buffer"])
        ] = odd
    elif target == "buffer":
        document["buffers"][0]["uri"] = rng.choice(
            ["file:///etc/passwd", "http://x/y.bin", "data:;base64,@@", odd]
        )
    elif target == "node":
        node = rng.choice(document["nodes"])
        node[rng.choice(["matrix", "children", "mesh", "translation", "rotation"])] = rng.choice(
            [odd, [odd] * 16, [0]]
        )
    elif target == "mesh":
        primitive = document["meshes"][0]["primitives"][0]
        primitive[rng.choice(["indices", "mode", "material", "attributes"])] = odd
    elif target == "material":
        document["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = rng.choice([odd, [odd] * 4])
    else:
        document.pop(rng.choice(list(document)))
    return document


def test_10000_mutated_documents_and_forms_get_only_400s(renderer: Any) -> None:
    import resource

    from viewer_bridge.render.server import BadRequest, render_request

    rng = random.Random(11)
    base = json.loads(sample_gltf())
    fields = list(form(b"").keys())
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    outcomes = {"png": 0, "400": 0}
    for _ in range(10_000):
        scene = json.dumps(mutate(base, rng)).encode()
        overrides: dict[str, Any] = {}
        if rng.random() < 0.3:
            overrides[rng.choice(fields[2:])] = rng.choice(
                [None, b"", b"nan", b"-1", b"1e400", b"\xff", b"99999"]
            )
        try:
            render_request(form(scene, **overrides), renderer.render)
            outcomes["png"] += 1
        except BadRequest:
            outcomes["400"] += 1
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    print(f"outcomes {outcomes}, peak memory grew {grown_mb:.0f} MB")
    assert outcomes["400"] > 3000 and grown_mb < 500


def test_snapshot_of_a_drake_log_shows_the_scene(drake_log: Path, tmp_path: Path) -> None:
    from PIL import Image

    from viewer_bridge.render.renderer import Camera
    from viewer_bridge.render.snapshot import latest_scene, look_at
    from viewer_bridge.transports.lcm import read_log

    out = tmp_path / "snap.png"
    eye, target = "0.9,0.5,4", "0.9,0.5,0"  # from above the bodies
    result = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "snapshot", str(drake_log), str(out), "--role", "illustration",
         "--image", "label", "--camera", f"{eye},{target}", "--size", "320x240"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    pixels = np.array(Image.open(out))
    scene = latest_scene(list(read_log(drake_log)), "ILLUSTRATION")
    pose = look_at(np.array([0.9, 0.5, 4.0]), np.array([0.9, 0.5, 0.0]))
    focal = 120 / np.tan(np.radians(45.0) / 2)
    camera = Camera(320, 240, focal, focal, 160, 120, 0.01, 100.0, pose)
    checked = 0
    for link in scene.links:
        if not link.name.endswith(
            ("body0", "body1", "body4")
        ):  # box, sphere, ellipsoid: their centres are theirs
            continue
        geometry = link.geometries[0]
        center = scene.link_pose(link).compose(geometry.pose).position
        eye_point = np.linalg.inv(camera.pose) @ np.array([*center, 1.0])
        column = int(round(camera.center_x + camera.focal_x * eye_point[0] / -eye_point[2]))
        row = int(round(camera.center_y - camera.focal_y * eye_point[1] / -eye_point[2]))
        expected = np.round(np.array(geometry.color[:3]) * 255)
        assert np.array_equal(pixels[row, column], expected), (link.name, pixels[row, column], expected)
        checked += 1
    assert checked == 6


def test_the_http_endpoint_answers_400_with_a_reason(render_url: str) -> None:
    import urllib.error
    import urllib.request

    boundary = "xyzzy"
    fields = form(sample_gltf(), image_type=b"normals")
    body = (
        b"".join(
            f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"\r\n\r\n'.encode()
            + value
            + b"\r\n"
            for name, value in fields.items()
        )
        + f"--{boundary}--\r\n".encode()
    )
    request = urllib.request.Request(f"{render_url}/render", data=body, method="POST",
                                     headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})  # fmt: skip
    with pytest.raises(urllib.error.HTTPError) as caught:
        urllib.request.urlopen(request, timeout=20)
    assert caught.value.code == 400 and b"unsupported image_type 'normals'" in caught.value.read()
    document = json.loads(sample_gltf())
    document["buffers"][0]["uri"] = "file:///etc/passwd"
    from viewer_bridge.render.server import BadRequest, parse_form, render_request

    with pytest.raises(BadRequest, match="only embedded data: URIs"):
        render_request(form(json.dumps(document).encode()), lambda *args: np.zeros((1, 1, 4)))
    with pytest.raises(BadRequest, match="multipart"):
        parse_form("application/json", b"{}")


def test_uploads_above_the_cap_are_refused_unread() -> None:
    import urllib.error
    import urllib.request

    server, url = start_server("--max-upload", "1000")
    try:
        request = urllib.request.Request(f"{url}/render", data=b"x" * 2000, method="POST",
                                         headers={"Content-Type": "multipart/form-data; boundary=b"})  # fmt: skip
        with pytest.raises(urllib.error.HTTPError) as caught:
            urllib.request.urlopen(request, timeout=20)
        assert caught.value.code == 400 and b"above the limit of 1000" in caught.value.read()
    finally:
        server.terminate()
        server.wait(timeout=10)


def test_a_page_of_a_foreign_origin_may_not_post_renders() -> None:
    """A browser page may post a form to any address; the server takes posts from Drake's client
    (no Origin), loopback pages and the origins `--allow-origin` names, and answers others 403
    before it reads their upload."""
    import urllib.error
    import urllib.request

    server, url = start_server(
        "--allow-origin", "https://lab.example", "--allow-origin", "https://*.corp.example"
    )
    try:

        def status(origin: str | None) -> tuple[int, bytes]:
            headers = {"Content-Type": "multipart/form-data; boundary=b"} | (
                {"Origin": origin} if origin else {}
            )
            request = urllib.request.Request(
                f"{url}/render", data=b"--b--\r\n", method="POST", headers=headers
            )
            with pytest.raises(urllib.error.HTTPError) as caught:  # a form with no fields: 400 when let in
                urllib.request.urlopen(request, timeout=20)
            return caught.value.code, caught.value.read()

        for origin in (
            None,
            "http://localhost:5173",
            "http://127.0.0.1",
            "https://lab.example",
            "https://x.corp.example",
        ):
            assert status(origin)[0] == 400, origin
        code, body = status("https://evil.example")
        assert code == 403
        assert b"render request from origin https://evil.example refused (403)" in body
        assert b"serve-render --allow-origin 'https://evil.example'" in body
    finally:
        server.terminate()
        server.wait(timeout=10)
    refused = subprocess.run([sys.executable, "-m", "viewer_bridge.cli.main", "serve-render", "--allow-origin", "https://x/"],
                             capture_output=True, text=True, timeout=60)  # fmt: skip
    assert refused.returncode == 2 and "'https://x/' is no origin" in refused.stderr
