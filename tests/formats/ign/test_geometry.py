"""Shapes as ign/gz `Geometry`: the table's type codes are Debian's, and what the bridge reads back."""

from __future__ import annotations

from types import ModuleType

import pytest

from tests.formats.ign.oracle import xyz
from viewer_bridge.errors import SceneError
from viewer_bridge.formats.ign.model import model, scene_from_model
from viewer_bridge.formats.mappings import tables
from viewer_bridge.model.scene import Box, Geometry, HalfSpace, Link, Scene


def test_geometry_type_codes_are_debians(debian_ign_msgs: ModuleType) -> None:
    table = tables("ign")["geometry"]
    assert dict(table.types) == dict(debian_ign_msgs.Geometry.Type.items())


def test_half_space_is_a_plane() -> None:
    scene = Scene((Link("world", 0, (Geometry(HalfSpace()),)),))
    visual = model(scene).link[0].visual[0]
    assert visual.geometry.type == tables("ign")["geometry"].types["PLANE"]
    assert xyz(visual.geometry.plane.normal) == [0, 0, 1] and visual.geometry.plane.size.x == 50
    assert scene_from_model(model(scene)).links[0].geometries[0].shape == HalfSpace()


@pytest.mark.parametrize("obj", ["v 1 2\n", "v 0 0 0\n\nf 1 2\n", "v 0 0 0\nf 1 1 9\n", "v nan 0 0\n"])
def test_mesh_array_objs_that_do_not_hold_together(obj: str) -> None:
    import base64

    message = model(Scene((Link("l", 0, (Geometry(Box((1.0, 1.0, 1.0))),)),)))
    geometry = message.link[0].visual[0].geometry
    geometry.type = 6
    geometry.mesh.filename = "data:model/obj;base64," + base64.b64encode(obj.encode()).decode()
    with pytest.raises(SceneError, match="mesh array OBJ"):
        scene_from_model(message)
