"""The load targets and the settransform path, timed as the base commit (65407f5) and as this
checkout write them, each in a child process (`times`), for `bench/translators.py`.

The base side is the base commit's package, unpacked with `git archive`: so what runs on that
side (`base_calls`) uses only what both versions have, and each side imports the format modules
by its own names and paths, in the function that uses them. The package was `bridge` then (it
is `viewer_bridge` since), and its `bridge/formats/ros.py` and `ros_tf.py` are
`viewer_bridge/formats/ros/` here, its `drake.py` is `viewer_bridge/formats/drake/`. The scenes
and frames both sides time are built by this module and `common.py` from `viewer_bridge.model.scene`:
in the base side's process that name stands for the base commit's own `bridge.scene`, so that
its code gets its own classes.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from common import best_of, frame

from viewer_bridge.model.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    Geometry,
    Link,
    LinkPoses,
    Scene,
    Sphere,
)
from viewer_bridge.model.scene import Pose as ScenePose

BASE_COMMIT = "65407f5"
BASE_PACKAGE = "bridge"  # the import package's name at BASE_COMMIT

# A side's process: its package must be the side's own code (the folder given), not the installed one.
_CHILD = """
import importlib, json, sys
folder, package_name, side, links, repeat = sys.argv[1:]
package = importlib.import_module(package_name)
assert package.__file__.startswith(folder), package.__file__
if package_name != "viewer_bridge":  # the base commit's scene classes, under the name this module imports
    sys.modules["viewer_bridge"] = package
    sys.modules["viewer_bridge.model.scene"] = importlib.import_module(package_name + ".scene")
from load_targets import _time
print(json.dumps(_time(side, links, repeat)))
"""


def scene(links: int) -> Scene:
    """One primitive per link, cycling through the shapes (a 1000-link load has 1000 geometries)."""
    shapes = [
        Box((0.1, 0.2, 0.3)),
        Sphere(0.05),
        Cylinder(0.04, 0.3),
        Capsule(0.03, 0.2),
        Ellipsoid((0.1, 0.2, 0.3)),
    ]
    names = frame(links).names
    geometry = [Geometry(shape, ScenePose((0.1, 0.0, 0.0)), (0.5, 0.5, 0.5, 1.0)) for shape in shapes]
    return Scene(tuple(Link(name, index % 7, (geometry[index % 5],)) for index, name in enumerate(names)))


def inputs(side: str, links: int) -> tuple[Scene, LinkPoses]:
    """The load (with a frame's poses) and a draw as the side's decoder hands it over (float32 views)."""
    if side == "base":
        from bridge.formats.drake import DrawDecoder, DrawEncoder  # the base commit's one module
    else:
        from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder  # a package here
    load = scene(links).with_poses(frame(links))
    draw = DrawDecoder().decode(DrawEncoder().encode(frame(links, seed=1)))
    return load, draw


def base_calls(load: Scene, draw: LinkPoses) -> dict[str, Callable[[], object]]:
    """Each measured path as the base commit writes it."""
    from bridge.formats import foxglove, ign, ros, ros_tf  # the base commit's modules: one file each then
    from bridge.formats import tree_viewer as tv  # the base commit's one module (a package since)

    frames = ros_tf.FrameNames()
    return {
        "settransform": lambda: tv.encode(tv.draw_request(draw)),
        "MarkerArray": lambda: ros.marker_array_cdr(load),
        "ign Model": lambda: ign.model(load).SerializeToString(),
        "tree viewer setgeometry": lambda: [tv.encode(request) for request in tv.load_requests(load)],
        "Foxglove SceneUpdate": lambda: foxglove.scene_update(load, frames).SerializeToString(),
        "shape_msgs": lambda: [ros.to_cdr(posed.shape) for posed in ros.shapes(load)],
    }


def our_calls(load: Scene, draw: LinkPoses) -> dict[str, Callable[[], object]]:
    """Each path of `base_calls` as this checkout writes it (the same bytes; only called here)."""
    from viewer_bridge.formats.foxglove.scene import (
        scene_update,  # packages here, one module each in the base commit
    )
    from viewer_bridge.formats.ign.model import model_bytes
    from viewer_bridge.formats.ros.markers import marker_array_cdr
    from viewer_bridge.formats.ros.shapes import shapes_cdr
    from viewer_bridge.formats.ros.tf import FrameNames
    from viewer_bridge.formats.tree_viewer import envelope
    from viewer_bridge.formats.tree_viewer.requests import SettransformEncoder, load_requests

    frames = FrameNames()
    settransform = SettransformEncoder()
    return {
        "settransform": lambda: settransform.encode(draw),
        "MarkerArray": lambda: marker_array_cdr(load),
        "ign Model": lambda: model_bytes(load),
        "tree viewer setgeometry": lambda: [envelope.encode(request) for request in load_requests(load)],
        "Foxglove SceneUpdate": lambda: scene_update(load, frames).SerializeToString(),
        "shape_msgs": lambda: shapes_cdr(load),
    }


def times(side: str, links: int, repeat: int) -> dict[str, float]:
    """Seconds per call of each path, "base" (the base commit's code, unpacked with `git archive`)
    or "ours" (this checkout), each in a child process of its own so that both sides run with
    the same modules loaded."""
    root = Path(__file__).resolve().parent.parent
    with tempfile.TemporaryDirectory() as folder:
        if side == "base":
            archive = subprocess.run(["git", "-C", str(root), "archive", BASE_COMMIT, BASE_PACKAGE, "mappings", "lcmtypes"],
                                     check=True, capture_output=True).stdout  # fmt: skip
            subprocess.run(["tar", "-x", "-C", folder], input=archive, check=True)
        # The working directory comes first on sys.path, before the editable install.
        where = folder if side == "base" else str(root)
        package = BASE_PACKAGE if side == "base" else "viewer_bridge"
        environment = {**os.environ, "PYTHONPATH": f"{where}:{Path(__file__).parent}"}
        result = subprocess.run([sys.executable, "-c", _CHILD, where, package, side, str(links), str(repeat)],
                                check=True, capture_output=True, text=True, cwd=where, env=environment)  # fmt: skip
    seconds: dict[str, float] = json.loads(result.stdout)
    return seconds


def _time(side: str, links: str, repeat: str) -> dict[str, float]:
    load, draw = inputs(side, int(links))
    calls = base_calls(load, draw) if side == "base" else our_calls(load, draw)
    for call in calls.values():
        call()  # warm: tables loaded, caches filled, as in a running bridge
    return {name: best_of(call, int(repeat)) for name, call in calls.items()}
