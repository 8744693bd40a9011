"""A load as static Rerun chunks: an entity per link, one per geometry, sizes by mappings/rerun.yaml;
a geometry Rerun cannot show is skipped alone, with a named warning."""

from __future__ import annotations

import numpy as np

from viewer_bridge.formats.rerun.scene import scene_chunks
from viewer_bridge.model.scene import (
    Box,
    Capsule,
    Cylinder,
    Geometry,
    HalfSpace,
    Link,
    MeshFile,
    Pose,
    Scene,
    Sphere,
    TriangleMesh,
    frame_name,
)
from viewer_bridge.model.skipped import SkippedGeometry, collecting


def _rows(scene: Scene) -> dict[str, dict[str, object]]:
    rows = {}
    for part in scene_chunks(scene, ("drake",), frame_name):
        (chunk,) = part.chunks
        assert chunk.is_static
        (rows[chunk.entity_path],) = chunk.to_record_batch().to_pylist()
    return rows


def test_each_shape_is_its_archetype_with_the_loads_sizes() -> None:
    mesh = TriangleMesh(np.eye(3), np.array([[0, 1, 2]]))
    link = Link(
        "plant::robot::arm",
        1,
        (
            Geometry(Box((1.0, 2.0, 3.0)), Pose((1.0, 0.0, 0.0)), (1.0, 0.0, 0.0, 0.5)),
            Geometry(Sphere(0.25)),
            Geometry(Cylinder(0.1, 0.4)),
            Geometry(Capsule(0.1, 0.4)),
            Geometry(mesh),
            Geometry(HalfSpace()),
        ),
    )
    rows = _rows(Scene((link,)))
    base = "/drake/plant/robot/arm"
    assert rows[base]["CoordinateFrame:frame"] == ["plant/robot/arm"]
    box = rows[f"{base}/0"]
    assert box["Boxes3D:half_sizes"] == [[0.5, 1.0, 1.5]]
    assert box["Boxes3D:colors"] == [0xFF000080]  # alpha kept
    assert box["InstancePoses3D:translations"] == [[1.0, 0.0, 0.0]]
    assert rows[f"{base}/1"]["Ellipsoids3D:half_sizes"] == [[0.25, 0.25, 0.25]]
    assert np.allclose(rows[f"{base}/2"]["Cylinders3D:lengths"], [0.4])
    capsule = rows[f"{base}/3"]
    assert np.allclose(capsule["Capsules3D:translations"], [[0.0, 0.0, -0.2]])  # centred as Drake's
    assert len(rows[f"{base}/4"]["Mesh3D:vertex_positions"]) == 3
    assert rows[f"{base}/5"]["Boxes3D:half_sizes"] == [[25.0, 25.0, 0.5]]  # Drake's 50 x 50 x 1 ground


def test_a_geometry_rerun_cannot_show_is_skipped_alone(tmp_path: object) -> None:
    link = Link("plant::m::l", 1, (Geometry(MeshFile("/nowhere/part.vtk")), Geometry(Box((1.0, 1.0, 1.0)))))
    with collecting() as skipped:
        rows = _rows(Scene((link,)))
    assert [str(item) for item in skipped] == [
        "plant::m::l geometry 0 skipped: Rerun's Asset3D reads .glb, .gltf, .obj, .stl files, not .vtk (/nowhere/part.vtk)"
    ]
    assert isinstance(skipped[0], SkippedGeometry)
    assert set(rows) == {"/drake/plant/m/l", "/drake/plant/m/l/1"}
