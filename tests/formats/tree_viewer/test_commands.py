"""Bad geometry and transform objects in tree viewer commands: each a `SceneError` naming the field,
answered with status -3."""

from __future__ import annotations

from typing import Any

import pytest

from viewer_bridge.errors import SceneError
from viewer_bridge.formats.tree_viewer.envelope import ERROR_HANDLING_REQUEST
from viewer_bridge.formats.tree_viewer.tree import TreeState


@pytest.mark.parametrize(
    ("command", "reason"),
    [
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "teapot"}}]}, "unknown geometry type 'teapot'"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "box", "lengths": [1]}}]}, "box needs 3 values"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "sphere", "radius": "big"}}]}, "must be a number"),
        ({"setgeometry": [{"path": "a", "geometry": {"type": "sphere", "radius": 1}}]}, "path must be a list"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "pointcloud"}}]}, "points must be a list"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "pointcloud", "points": [[0, 0, 0]],
                                                        "channels": {"rgb": []}}}]}, "one per point"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "line", "points": [[0, 0, 0]]}}]}, "2 or more"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "triad", "tube": "yes"}}]}, "true or false"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "planar_lidar", "ranges": [1]}}]}, "angle_start"),
        ({"settransform": [{"path": ["a"], "transform": {"quaternion": [0, 0, 0, 0]}}]}, "length 0 is not a rotation"),
        ({"settransform": [{"path": ["a"], "transform": {"translation": [1, None, 2]}}]}, "3 finite numbers"),
        ({"setgeometry": [{"path": ["a"], "geometry": {"type": "mesh_data", "vertices": [[0, 0, 0]],
                                                        "faces": [[0, 1, 2]]}}]}, "faces refer to a vertex"),
    ],
)  # fmt: skip
def test_bad_commands_raise_scene_errors(command: dict[str, Any], reason: str) -> None:
    state = TreeState()
    with pytest.raises(SceneError, match=reason):
        state.apply(command)
    assert state.respond(command) == {"timestamp": 0, "status": ERROR_HANDLING_REQUEST, "error": ANY_TEXT}


class _AnyText:
    def __eq__(self, other: object) -> bool:
        return isinstance(other, str) and len(other) > 10


ANY_TEXT: Any = _AnyText()
