"""Drake's `lcmt_viewer_load_robot` (viewer_bridge/formats/drake/load.py), checked against real Drake's
traffic, and hand-made scenes through it both ways."""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.load import decode_load, link_from_lcm, load_from_scene, scene_from_load
from viewer_bridge.lcmcodec.codecs import GEOMETRY_DATA, LINK_DATA, LOAD_ROBOT, codec_for
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
    MeshFile,
    Pose,
    Scene,
    Sphere,
    TriangleMesh,
)
from viewer_bridge.transports.lcm import LcmEvent


def load_of(drake_events: list[LcmEvent], role: str) -> tuple[bytes, Scene]:
    data = next(e.data for e in drake_events if e.channel == f"DRAKE_VIEWER_LOAD_ROBOT_{role}")
    return data, decode_load(data)


@pytest.mark.parametrize("role", ["ILLUSTRATION", "PROXIMITY"])
def test_scene_round_trip_is_byte_identical(drake_events: list[LcmEvent], role: str) -> None:
    data, scene = load_of(drake_events, role)
    assert load_from_scene(scene).encode() == data


def test_every_shape_reads_with_its_parameters(drake_events: list[LcmEvent], drake_mesh_dir: Path) -> None:
    _, scene = load_of(drake_events, "ILLUSTRATION")
    links = {link.name: link for link in scene.links}
    assert links["world"].robot_num == 0
    (ground,) = links["world"].geometries
    assert ground.shape == Box((50.0, 50.0, 1.0))  # HalfSpace, as Drake lowers it
    assert ground.pose.position == pytest.approx((0.0, 0.0, -0.6))
    shapes = [links[f"plant::robot0::body{i}"].geometries[0].shape for i in range(8)]
    f32 = pytest.approx
    assert shapes[0] == Box((f32(0.1), f32(0.2), f32(0.3)))
    assert shapes[1] == Sphere(f32(0.05))
    assert shapes[2] == Cylinder(radius=f32(0.04), length=f32(0.3))  # radius first in Drake
    assert shapes[3] == Capsule(radius=f32(0.03), length=f32(0.2))
    assert shapes[4] == Ellipsoid((f32(0.1), f32(0.2), f32(0.3)))
    assert shapes[5] == MeshFile(str(drake_mesh_dir / "tetrahedron.obj"), (2.0, 2.0, 2.0))
    convex = shapes[6]
    assert isinstance(convex, TriangleMesh)  # Convex arrives as its hull, as a mesh array
    assert convex.triangles.shape == (4, 3) and convex.vertices.max() == pytest.approx(0.15)
    in_memory = shapes[7]
    assert isinstance(in_memory, InMemoryMesh)
    assert in_memory.mesh_file.extension == ".obj" and in_memory.scale == (0.5, 0.5, 0.5)
    assert in_memory.mesh_file.contents.decode().startswith("v 0 0 0\nv 0.1 0 0")
    robots = {link.robot_num for name, link in links.items() if name.startswith("plant::robot1::")}
    assert len(robots) == 1 and robots != {links["plant::robot0::body0"].robot_num}


def test_proximity_meshes_are_mesh_arrays(drake_events: list[LcmEvent]) -> None:
    _, scene = load_of(drake_events, "PROXIMITY")
    links = {link.name: link for link in scene.links}
    for index in (5, 6, 7):
        shape = links[f"plant::robot0::body{index}"].geometries[0].shape
        assert isinstance(shape, TriangleMesh), index


def test_geometry_pose_is_w_first(drake_events: list[LcmEvent]) -> None:
    data, scene = load_of(drake_events, "ILLUSTRATION")
    raw = LOAD_ROBOT.decode(data)
    link_index = [link.name for link in raw.link].index("plant::robot1::body2")
    geometry = scene.links[link_index].geometries[0]
    assert list(geometry.pose.quaternion_wxyz) == raw.link[link_index].geom[0].quaternion
    w, x, y, z = geometry.pose.quaternion_wxyz
    assert geometry.pose.quaternion_xyzw == (x, y, z, w)
    assert w == pytest.approx(np.cos(0.5 * np.linalg.norm([0.2, 0.2, 1.3])), abs=0.2)  # not tiny: w leads


def test_deformable_channel_decodes_as_link_data(drake_events: list[LcmEvent]) -> None:
    event = next(e for e in drake_events if e.channel.startswith("DRAKE_VIEWER_DEFORMABLE"))
    assert codec_for(event.data) is LINK_DATA
    link = link_from_lcm(LINK_DATA.decode(event.data))
    assert link.name == "deformable_geometries" and link.geometries == ()  # no deformables here


# --- hand-made scenes: every shape both ways, and what is refused -------------------------------


def every_shape_scene() -> Scene:
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    geometries = (
        Geometry(Box((1.0, 2.0, 3.0))),
        Geometry(Sphere(0.5), Pose((1.0, 2.0, 3.0), (0.5, 0.5, 0.5, 0.5)), (0.25, 0.5, 0.75, 1.0)),
        Geometry(Cylinder(0.25, 2.0)),
        Geometry(Capsule(0.25, 1.0)),
        Geometry(Ellipsoid((1.0, 2.0, 3.0))),
        Geometry(MeshFile("/meshes/a.obj", (1.0, 2.0, 0.5))),
        Geometry(TriangleMesh(vertices, np.array([[0, 1, 2]]))),
        Geometry(
            InMemoryMesh(
                FileContents(b"v 0 0 0\n", ".obj", "a.obj"),
                {"a.mtl": "/x/a.mtl", "t.png": FileContents(b"\x89PNG", ".png")},
            )
        ),
    )
    return Scene((Link("plant::model::link", 3, geometries),))


def test_scene_to_load_to_scene_is_lossless() -> None:
    scene = every_shape_scene()
    data = load_from_scene(scene).encode()
    assert decode_load(data) == scene
    raw = LOAD_ROBOT.decode(data).link[0].geom
    assert [g.type for g in raw] == [1, 2, 3, 5, 6, 4, 4, 4]
    assert raw[2].float_data == [0.25, 2.0]  # cylinder: radius first
    assert raw[6].float_data == [3, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 2]


def test_half_space_lowers_like_drake() -> None:
    scene = Scene((Link("world", 0, (Geometry(HalfSpace(), Pose((0.0, 0.0, 1.0))),)),))
    (geometry,) = LOAD_ROBOT.decode(load_from_scene(scene).encode()).link[0].geom
    assert geometry.type == 1 and geometry.float_data == [50.0, 50.0, 1.0]
    assert geometry.position == [0.0, 0.0, 0.5]


def load_with(geometry: Any) -> bytes:
    link = LINK_DATA.message_class(name="l", num_geom=1, geom=[geometry])
    return LOAD_ROBOT.message_class(num_links=1, link=[link]).encode()


def mesh_json(document: Any) -> str:
    return document if isinstance(document, str) else json.dumps(document)


@pytest.mark.parametrize(
    ("type_code", "float_data", "string_data", "field", "reason"),
    [
        (9, [], "", "link[0].geom[0].type", "unknown geometry type 9"),
        (1, [1.0, 2.0], "", "link[0].geom[0].float_data", "box needs 3 values in float_data, got 2"),
        (3, [1.0], "", "link[0].geom[0].float_data", "cylinder needs 2 values in float_data"),
        (
            4,
            [3.0, 1.0, 0, 0, 0, 1, 0, 0, 0, 1, 0],
            "",
            "link[0].geom[0].float_data",
            "needs 14 floats, got 11",
        ),
        (4, [1.5, 0.0, 0, 0, 0], "", "link[0].geom[0].float_data", "not a whole number"),
        (
            4,
            [1.0, 1.0, 0, 0, 0, 0, 1, 5],
            "",
            "link[0].geom[0].float_data",
            "index 1.0 is not a vertex index",
        ),
        (4, [1.0], '{"in_memory_mesh": ', "link[0].geom[0].string_data", "in-memory mesh JSON"),
        (4, [1.0], mesh_json({"in_memory_mesh": {}}), "link[0].geom[0].string_data", "no object 'mesh_file'"),
        (
            4,
            [1.0],
            mesh_json({"in_memory_mesh": {"mesh_file": {"contents": 1, "extension": ".obj"}}}),
            "link[0].geom[0].string_data",
            "needs string 'contents'",
        ),
        (
            4,
            [1.0],
            mesh_json({"in_memory_mesh": {"mesh_file": {"contents": "!!", "extension": ".obj"}}}),
            "link[0].geom[0].string_data",
            "not base64",
        ),
        (
            4,
            [1.0],
            mesh_json(
                {
                    "in_memory_mesh": {
                        "mesh_file": {"contents": "", "extension": ".obj"},
                        "supporting_files": [],
                    }
                }
            ),
            "link[0].geom[0].string_data",
            "supporting_files is not an object",
        ),
    ],
)
def test_shapes_that_make_no_sense_raise_decode_errors(
    type_code: int, float_data: list[float], string_data: str, field: str, reason: str
) -> None:
    geometry = GEOMETRY_DATA.message_class(
        type=type_code,
        quaternion=[1.0, 0, 0, 0],
        string_data=string_data,
        num_float_data=len(float_data),
        float_data=float_data,
    )
    with pytest.raises(DecodeError) as caught:
        decode_load(load_with(geometry))
    assert caught.value.field == field and caught.value.type_name == "drake.lcmt_viewer_load_robot"
    assert reason in caught.value.reason


def test_json_error_offset_points_into_the_text() -> None:
    text = '{"in_memory_mesh": {"mesh_file": nope}}'
    geometry = GEOMETRY_DATA.message_class(type=4, string_data=text, num_float_data=1, float_data=[1.0])
    with pytest.raises(DecodeError) as caught:
        scene_from_load(LOAD_ROBOT.decode(load_with(geometry)))
    assert caught.value.unit == "character" and text[caught.value.offset :].startswith("nope")


def test_in_memory_mesh_json_matches_drakes_writing() -> None:
    contents = base64.b64encode(b"v 1 2 3\n").decode()
    text = json.dumps(
        {
            "in_memory_mesh": {
                "mesh_file": {"contents": contents, "extension": ".obj", "filename_hint": "x.obj"}
            }
        },
        separators=(",", ":"),
    )
    geometry = GEOMETRY_DATA.message_class(
        type=4, string_data=text, num_float_data=3, float_data=[1.0, 1.0, 1.0]
    )
    data = load_with(geometry)
    assert load_from_scene(decode_load(data)).encode() == data
