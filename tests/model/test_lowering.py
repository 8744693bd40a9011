"""Lowerings: shapes rewritten for targets that lack them."""

from __future__ import annotations

import numpy as np
import pytest

from viewer_bridge.errors import SceneError
from viewer_bridge.model.lowering import LOWERINGS, capsule_parts, triangle_mesh
from viewer_bridge.model.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    FileContents,
    HalfSpace,
    InMemoryMesh,
    MeshFile,
    Pose,
    Sphere,
    TriangleMesh,
)


@pytest.mark.parametrize(
    ("shape", "half_extent"),
    [
        (Box((1.0, 2.0, 3.0)), [0.5, 1.0, 1.5]),
        (Sphere(0.5), [0.5, 0.5, 0.5]),
        (Cylinder(0.5, 2.0), [0.5, 0.5, 1.0]),
        (Capsule(0.5, 2.0), [0.5, 0.5, 1.5]),  # the caps add a radius at each end
        (Ellipsoid((1.0, 2.0, 3.0)), [1.0, 2.0, 3.0]),
    ],
)
def test_tessellations_fill_the_shape(shape: object, half_extent: list[float]) -> None:
    mesh = triangle_mesh(shape)  # type: ignore[arg-type]
    extent = np.abs(mesh.vertices).max(axis=0)
    assert (extent <= np.asarray(half_extent) + 1e-9).all() and (
        extent >= 0.85 * np.asarray(half_extent)
    ).all()
    assert mesh.triangles.min() >= 0 and mesh.triangles.max() < len(mesh.vertices)


def test_half_space_tessellates_as_drakes_box() -> None:
    mesh = triangle_mesh(HalfSpace())
    assert mesh.vertices[:, 2].max() == 0.0 and mesh.vertices[:, 2].min() == -1.0
    assert mesh.vertices[:, 0].max() == 25.0


def test_capsule_parts_are_a_cylinder_and_two_spheres() -> None:
    parts = capsule_parts(Capsule(0.5, 2.0))
    assert parts == [
        (Cylinder(0.5, 2.0), Pose()),
        (Sphere(0.5), Pose((0.0, 0.0, 1.0))),
        (Sphere(0.5), Pose((0.0, 0.0, -1.0))),
    ]
    assert LOWERINGS["capsule_parts"].produces == ("cylinder", "sphere")


def test_meshes_are_read_with_trimesh(tmp_path: object) -> None:
    obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    mesh = triangle_mesh(InMemoryMesh(FileContents(obj, ".obj", "t.obj"), scale=(2.0, 2.0, 2.0)))
    assert mesh.vertices.tolist() == [[0, 0, 0], [2, 0, 0], [0, 2, 0]] and mesh.triangles.tolist() == [
        [0, 1, 2]
    ]
    same = TriangleMesh(np.eye(3), np.array([[0, 1, 2]]))
    assert triangle_mesh(same) is same


@pytest.mark.parametrize(
    ("shape", "reason"),
    [
        (MeshFile("/no/such/file.obj"), "mesh file /no/such/file.obj does not exist"),
        (InMemoryMesh(FileContents(b"not a mesh at all", ".obj", "junk.obj")), "junk.obj has no triangles"),
        (InMemoryMesh(FileContents(b"\x00\x01", ".xyz", "odd.xyz")), "odd.xyz could not be read"),
    ],
)
def test_unreadable_meshes_are_scene_errors(shape: object, reason: str) -> None:
    with pytest.raises(SceneError, match=reason):
        triangle_mesh(shape)  # type: ignore[arg-type]
