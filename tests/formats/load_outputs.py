"""Each load target's bytes for a few fixed scenes, as sha256 digests: what the tests hold the
optimised load paths to. `load_digests.json` was written by running this module on the code
before the optimisations (commit 65407f5), and must not change; one entry was corrected by
hand: ign refused a point cloud with a TypeError, now a SceneError (a bug fixed since); and six
were recorded again when foxglove and ign stopped refusing the whole scene for its point cloud
(issue 26: they skip that geometry alone). Written by:

    .venv/bin/python -m tests.formats.load_outputs > tests/formats/load_digests.json
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from bridge.formats import foxglove, ign, ros
from bridge.formats import tree_viewer as tv
from bridge.formats.ros_tf import FrameNames
from bridge.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    FileContents,
    Geometry,
    HalfSpace,
    InMemoryMesh,
    Line,
    Link,
    LinkPoses,
    MeshFile,
    PointCloud,
    Pose,
    Scene,
    Sphere,
    Triad,
    TriangleMesh,
)

TETRAHEDRON_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def poses_for(scene: Scene, seed: int) -> LinkPoses:
    rng = np.random.default_rng(seed)
    count = len(scene.links)
    quaternions = rng.normal(size=(count, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    return LinkPoses(
        1234,
        tuple(link.name for link in scene.links),
        np.array([link.robot_num for link in scene.links], dtype=np.int32),
        rng.normal(size=(count, 3)),
        quaternions,
    )


def primitives(links: int, seed: int) -> Scene:
    """One or two random primitives per link, random poses and colours."""
    rng = np.random.default_rng(seed)
    makers = [
        lambda: Box(tuple(rng.uniform(0.01, 1, 3).tolist())),
        lambda: Sphere(float(rng.uniform(0.01, 1))),
        lambda: Cylinder(float(rng.uniform(0.01, 1)), float(rng.uniform(0.01, 1))),
        lambda: Capsule(float(rng.uniform(0.01, 1)), float(rng.uniform(0.01, 1))),
        lambda: Ellipsoid(tuple(rng.uniform(0.01, 1, 3).tolist())),
        lambda: HalfSpace(),
    ]
    links_out = []
    for index in range(links):
        geometries = []
        for _ in range(int(rng.integers(1, 3))):
            quaternion = rng.normal(size=4)
            quaternion /= np.linalg.norm(quaternion)
            pose = Pose(tuple(rng.normal(size=3).tolist()), tuple(quaternion.tolist()))
            color = tuple(rng.uniform(0, 1, 4).tolist())
            geometries.append(Geometry(makers[int(rng.integers(0, len(makers)))](), pose, color))
        links_out.append(Link(f"plant::model{index % 4}::link_{index}", index % 4, tuple(geometries)))
    return Scene(tuple(links_out))


def every_kind(folder: Path) -> Scene:
    """Every shape kind, meshes from a file, in memory and as arrays, lines, triads, points."""
    obj = folder / "tetra.obj"
    obj.write_text(TETRAHEDRON_OBJ)
    shapes = [
        Box((0.1, 0.2, 0.3)), Sphere(0.05), Cylinder(0.04, 0.3), Capsule(0.03, 0.2), Ellipsoid((0.1, 0.2, 0.3)),
        HalfSpace(), MeshFile(str(obj), (1.0, 2.0, 3.0)),
        InMemoryMesh(FileContents(TETRAHEDRON_OBJ.encode(), ".obj", "t.obj"), {}, (2.0, 2.0, 2.0)),
        TriangleMesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])),
        PointCloud(np.array([[0.0, 0, 0], [1, 2, 3]]), np.array([[1.0, 0, 0], [0, 1, 0]])),
        Triad(0.5, True), Line(np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]]), 0.02, closed=True),
    ]  # fmt: skip
    tilted = Pose((0.1, -0.2, 0.3), (0.5, 0.5, 0.5, 0.5))
    return Scene(
        tuple(
            Link(f"plant::m::link_{index}", index % 3, (Geometry(shape, tilted, (0.1, 0.2, 0.3, 0.5)),))
            for index, shape in enumerate(shapes)
        )
    )


def targets() -> dict[str, Callable[[Scene], bytes]]:
    """Every load target, as bytes, by the paths the translators take (recorded: by the paths of
    the base commit, which wrote the same bytes from message objects)."""
    frames = FrameNames()
    return {
        "marker_array": lambda scene: ros.marker_array_cdr(scene),
        "marker_stream_load": lambda scene: ros.MarkerStream(scene).load_cdr,
        "markers_in_link_frames": lambda scene: ros.marker_array_in_link_frames_cdr(scene, frames),
        "ign_model": lambda scene: ign.model_bytes(scene),
        "ign_model_v": lambda scene: ign.model_v_bytes(scene),
        "tree_viewer": lambda scene: b"|".join(tv.encode(request) for request in tv.load_requests(scene)),
        "foxglove": lambda scene: foxglove.scene_update(scene, frames).SerializeToString(),
    }


def scenes(folder: Path) -> dict[str, Scene]:
    small = primitives(30, seed=1)
    large = primitives(300, seed=2)
    kinds = every_kind(folder)
    return {
        "primitives30": small,
        "primitives30_posed": small.with_poses(poses_for(small, 3)),
        "primitives300_posed": large.with_poses(poses_for(large, 4)),
        "every_kind": kinds,
        "every_kind_posed": kinds.with_poses(poses_for(kinds, 5)),
        # Foxglove and ign refuse point clouds: without them, their meshes and lines are covered.
        "every_kind_but_points": Scene(
            tuple(link for link in kinds.links if not isinstance(link.geometries[0].shape, PointCloud))
        ),
    }


def digests(folder: Path) -> dict[str, str]:
    """sha256 of every target's bytes for every scene; "refused" where the target refuses a shape."""
    out = {}
    for scene_name, scene in scenes(folder).items():
        for target_name, write in targets().items():
            try:
                # The file path is in the bytes of some targets: the same folder name every time.
                out[f"{scene_name}/{target_name}"] = hashlib.sha256(write(scene)).hexdigest()
            except Exception as error:  # noqa: BLE001 - what was raised is part of the record
                out[f"{scene_name}/{target_name}"] = f"refused: {type(error).__name__}"
    return out


FOLDER = Path(tempfile.gettempdir()) / "viewer-bridge-load-outputs"

if __name__ == "__main__":
    FOLDER.mkdir(exist_ok=True)
    print(json.dumps(digests(FOLDER), indent=1, sort_keys=True))
