"""One bad geometry never hides the rest: a recording whose load names a mesh file that is gone.

The demo's scene with its mesh file swapped for a path that does not exist, recorded as a log,
then converted (both schemas), snapshotted and run as a user would: every other geometry is
there, the missing mesh is a warning that names it, and the exit status is 0.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
from PIL import Image

from tests.cli.test_cli import run
from viewer_bridge.examples.demo import demo_poses, demo_scene
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.model.scene import Geometry, Link, MeshFile, Scene
from viewer_bridge.model.skipped import collecting, per_geometry
from viewer_bridge.transports.lcm import LcmEvent, read_log, write_log

GONE = "/nonexistent/viewer-bridge/gone.obj"


def with_mesh(scene: Scene, path: str | None) -> Scene:
    """The scene with its mesh file at `path` instead, or without that geometry (None)."""

    def swapped(geometry: Geometry) -> tuple[Geometry, ...]:
        if not isinstance(geometry.shape, MeshFile):
            return (geometry,)
        return () if path is None else (Geometry(MeshFile(path), geometry.pose, geometry.color),)

    return Scene(
        tuple(
            Link(link.name, link.robot_num, sum(map(swapped, link.geometries), ())) for link in scene.links
        ),
        scene.poses,
    )


def recording(folder: Path) -> Path:
    scene = with_mesh(demo_scene(), GONE)
    encoder = DrawEncoder()
    draws = [
        LcmEvent("DRAKE_VIEWER_DRAW", encoder.encode(demo_poses(scene, i / 60)), 2000 + i * 16_667)
        for i in range(5)
    ]
    log = folder / "gone.lcmlog"
    write_log(log, [LcmEvent("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode(), 1000), *draws])
    return log


def counts(stdout: str) -> dict[str, int]:
    """Messages per topic, from convert's table (its `wrote ...` summary line aside)."""
    rows = [line.split() for line in stdout.splitlines()]
    return {row[1]: int(row[0]) for row in rows if len(row) == 2 and row[0].isdigit()}


def test_per_geometry_skips_the_one_that_fails_and_names_it() -> None:
    from viewer_bridge.errors import SceneError

    link = Link("plant::a", 0, tuple(Geometry(MeshFile(str(index))) for index in range(3)))

    def write(index: int, geometry: Geometry) -> int:
        if index == 1:
            raise SceneError(f"mesh file {geometry.shape} is bad")
        return index

    with collecting() as skipped:
        assert per_geometry(link, write) == [0, 2]
    assert [str(item) for item in skipped] == [
        "plant::a geometry 1 skipped: mesh file MeshFile(path='1', scale=(1.0, 1.0, 1.0)) is bad"
    ]


def test_convert_to_ros2_writes_every_other_shape_and_warns(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    from viewer_bridge.formats.ros.shapes import shapes_cdr

    out = tmp_path / "gone.mcap"
    result = run("convert", str(recording(tmp_path)), str(out))
    assert result.returncode == 0, result.stderr
    assert f"demo::shapes::meshfile_5 geometry 0 skipped: mesh file {GONE} does not exist" in result.stderr
    expected = len(shapes_cdr(with_mesh(demo_scene(), None)))
    written = counts(result.stdout)
    assert written["/drake/shapes/primitives"] + written["/drake/shapes/meshes"] == expected > 0
    with out.open("rb") as file:
        topics = [channel.topic for _, channel, _ in make_reader(file).iter_messages()]
    assert sum(topic.startswith("/drake/shapes/") for topic in topics) == expected
    assert counts(result.stdout)["/drake/markers"] == 6  # the load's, then one per draw


def test_convert_to_foxglove_writes_the_scene_less_the_missing_mesh(tmp_path: Path) -> None:
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    from mcap.reader import make_reader

    from viewer_bridge.formats.foxglove.scene import scene_update

    out = tmp_path / "gone.mcap"
    result = run("convert", str(recording(tmp_path)), str(out), "--schema", "foxglove")
    assert result.returncode == 0, result.stderr
    assert f"mesh file {GONE} does not exist" in result.stderr
    with out.open("rb") as file:
        updates = [
            m.data for _, channel, m in make_reader(file).iter_messages() if channel.topic == "/drake/scene"
        ]
    assert len(updates) == 1
    written = SceneUpdate.FromString(updates[0])
    expected = scene_update(with_mesh(demo_scene(), None), lambda name: name)
    kinds = ("cubes", "spheres", "cylinders", "models", "triangles", "lines", "arrows")

    def primitives(update: SceneUpdate) -> dict[str, int]:
        return {entity.id: sum(len(getattr(entity, kind)) for kind in kinds) for entity in update.entities}

    assert primitives(written) == primitives(expected)
    assert sum(primitives(written).values()) >= 8  # every other shape of the demo


def test_snapshot_draws_every_other_geometry_and_names_the_missing_mesh(tmp_path: Path) -> None:
    from viewer_bridge.render.snapshot import latest_scene, snapshot

    out = tmp_path / "gone.png"
    log = recording(tmp_path)
    result = run("snapshot", str(log), str(out), "--size", "160x120")
    assert result.returncode == 0, result.stderr
    assert result.stderr.splitlines() == [
        f"viewer-bridge snapshot: warning: demo::shapes::meshfile_5 geometry 0 skipped: mesh file {GONE} does not exist"
    ]
    assert "(1 skipped)" in result.stdout
    scene = with_mesh(latest_scene(list(read_log(log))), None)
    without = np.asarray(Image.open(io.BytesIO(snapshot(scene, 160, 120))))
    assert np.array_equal(np.asarray(Image.open(out)), without)  # the same picture as with no mesh at all
    assert len(np.unique(without.reshape(-1, 3), axis=0)) > 5  # and it shows the other shapes


def test_run_publishes_every_other_shape_and_counts_the_warning(tmp_path: Path) -> None:
    stats = tmp_path / "stats.json"
    result = run(
        "run", "--set", "foxglove.port=0", "--lcm-url", f"file://{recording(tmp_path)}?speed=0",
        "--stats-json", str(stats), "--duration", "30",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert f"mesh file {GONE} does not exist" in result.stderr
    shapes = json.loads(stats.read_text())["routes"]["shapes"]
    assert shapes["warnings"] == {"skipped_geometry": 1} and shapes["errors"] == {}
    assert shapes["messages_out"] > 0


def test_targets_that_cannot_draw_a_point_cloud_write_the_rest_of_the_scene(tmp_path: Path) -> None:
    """Foxglove and ign have no point cloud shape: the scene is written without it, the same
    bytes as the scene whose link has no geometry, and the skip is named."""
    from tests.formats.load_outputs import every_kind
    from viewer_bridge.formats.foxglove.scene import scene_update
    from viewer_bridge.formats.ign.model import model_bytes, model_v_bytes
    from viewer_bridge.formats.ros.tf import FrameNames
    from viewer_bridge.model.scene import PointCloud

    scene = every_kind(tmp_path)
    bare = Scene(
        tuple(
            Link(link.name, link.robot_num, ()) if isinstance(link.geometries[0].shape, PointCloud) else link
            for link in scene.links
        )
    )
    targets = {
        "foxglove": lambda s: scene_update(s, FrameNames()).SerializeToString(),
        "ign_model": lambda s: model_bytes(s),
        "ign_model_v": lambda s: model_v_bytes(s),
    }
    for name, write in targets.items():
        with collecting() as skipped:
            written = write(scene)
        assert [item.link for item in skipped] == ["plant::m::link_9"], name
        assert "point_cloud" in skipped[0].reason
        with collecting() as none:
            assert written == write(bare), name
        assert not none
