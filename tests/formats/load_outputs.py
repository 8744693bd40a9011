"""Each load target's output for a few fixed scenes: what the tests hold the optimised load paths to.

`load_digests.json` holds the sha256 of every output, recorded by running this module on the code
before the optimisations (commit 65407f5); one entry was corrected by hand (ign refused a point
cloud with a TypeError, now a SceneError: a bug fixed since), the posed entries were recorded
again twice (see `test_every_load_target_writes_the_recorded_values`), and six when foxglove and
ign stopped refusing a whole scene for its point cloud (issue 26: they skip that geometry alone).
`load_outputs.tar.xz` holds the outputs themselves, one member per message, written on a machine
where every output had exactly its recorded digest. The digests hold the archive to its history
(hashing stored bytes involves no arithmetic); the test compares today's outputs with the
archive's by value, because composed poses differ in their last bits from one CPU or BLAS kernel
to another. Written by:

    .venv/bin/python -m tests.formats.load_outputs digests > tests/formats/load_digests.json
    .venv/bin/python -m tests.formats.load_outputs record   # load_outputs.tar.xz, checked against the digests
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
import tarfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from viewer_bridge.formats.foxglove.scene import scene_update
from viewer_bridge.formats.ign.model import model_bytes, model_v_bytes
from viewer_bridge.formats.ros.markers import MarkerStream, marker_array_cdr, marker_array_in_link_frames_cdr
from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.formats.tree_viewer.requests import load_requests
from viewer_bridge.model.scene import (
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


def targets() -> dict[str, Callable[[Scene], list[bytes]]]:
    """Every load target, as the messages it writes, by the paths the translators take (recorded:
    by the paths of the base commit, which wrote the same bytes from message objects)."""
    frames = FrameNames()
    return {
        "marker_array": lambda scene: [marker_array_cdr(scene)],
        "marker_stream_load": lambda scene: [MarkerStream(scene).load_cdr],
        "markers_in_link_frames": lambda scene: [marker_array_in_link_frames_cdr(scene, frames)],
        "ign_model": lambda scene: [model_bytes(scene)],
        "ign_model_v": lambda scene: [model_v_bytes(scene)],
        "tree_viewer": lambda scene: [envelope.encode(request) for request in load_requests(scene)],
        "foxglove": lambda scene: [scene_update(scene, frames).SerializeToString()],
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


Output = list[bytes] | str  # the messages a target wrote, or "refused: <error type>"


def outputs(folder: Path) -> dict[str, Output]:
    """Every target's messages for every scene ("scene/target"), its mesh files in `folder`."""
    out: dict[str, Output] = {}
    for scene_name, scene in scenes(folder).items():
        for target_name, write in targets().items():
            try:
                out[f"{scene_name}/{target_name}"] = write(scene)
            except Exception as error:  # noqa: BLE001 - what was raised is part of the record
                out[f"{scene_name}/{target_name}"] = f"refused: {type(error).__name__}"
    return out


def digest(output: Output) -> str:
    """sha256 of a target's messages joined by "|" (the form the digests were recorded in)."""
    return output if isinstance(output, str) else hashlib.sha256(b"|".join(output)).hexdigest()


def recorded_digests() -> dict[str, str]:
    recorded: dict[str, str] = json.loads(DIGESTS.read_text())
    return recorded


def recorded_outputs() -> dict[str, Output]:
    """The recorded outputs: the archive's messages, and the refusals the digests record."""
    out: dict[str, Output] = {
        name: value for name, value in recorded_digests().items() if value.startswith("refused")
    }
    with tarfile.open(ARCHIVE) as archive:
        members = sorted(archive.getmembers(), key=lambda member: int(member.name.rsplit("/", 1)[1]))
        for member in members:
            parts = out.setdefault(member.name.rsplit("/", 1)[0], [])
            file = archive.extractfile(member)
            assert isinstance(parts, list) and file is not None, member.name
            parts.append(file.read())
    return out


def record() -> None:
    """Write the archive from this machine's outputs, if each has exactly its recorded digest."""
    folder = Path(RECORDED_FOLDER)
    folder.mkdir(exist_ok=True)
    written = outputs(folder)
    differ = [name for name, expected in recorded_digests().items() if digest(written[name]) != expected]
    if differ:
        raise SystemExit(f"not recorded: outputs differ from their digests on this machine: {differ}")
    with tarfile.open(ARCHIVE, "w:xz", format=tarfile.PAX_FORMAT) as archive:  # one solid stream: 240 kB
        for name, output in sorted(written.items()):
            for index, part in enumerate([] if isinstance(output, str) else output):
                member = tarfile.TarInfo(f"{name}/{index}")
                member.size = len(part)
                archive.addfile(member, io.BytesIO(part))


# The recorded outputs name mesh files in this folder; a test writing elsewhere says where it wrote.
RECORDED_FOLDER = "/tmp/viewer-bridge-load-outputs"
DIGESTS = Path(__file__).with_name("load_digests.json")
ARCHIVE = Path(__file__).with_name("load_outputs.tar.xz")

if __name__ == "__main__":
    if sys.argv[1:] == ["record"]:
        record()
    elif sys.argv[1:] == ["digests"]:
        Path(RECORDED_FOLDER).mkdir(exist_ok=True)
        written = outputs(Path(RECORDED_FOLDER))
        print(
            json.dumps({name: digest(output) for name, output in written.items()}, indent=1, sort_keys=True)
        )
    else:
        raise SystemExit("usage: python -m tests.formats.load_outputs digests | record")
