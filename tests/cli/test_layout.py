"""`viewer-bridge layout`: the Foxglove layout file, read back as JSON, against the layout
foxglove-sdk's `foxglove.layouts` serialises for the topics the log's channels make.

The log is a Drake one: the demo scene in two roles, a camera's images as Drake's
ImageToLcmImageArrayT publishes them, Drake's `lcmt_iiwa_status`, and a channel of a type no one
knows. The topics expected are written out here from the built-in config's routes (what a
Foxglove client is announced for such a log), not taken from the code under test.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.drake_images import publish_with_drake
from tests.drake_robot_status import iiwa_status
from viewer_bridge.examples.demo import demo_poses, demo_scene
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.formats.foxglove.layout import LayoutTopics, foxglove_layout, numeric_paths
from viewer_bridge.transports.lcm import LcmEvent, write_log

SCENE, PROXIMITY_SCENE = "/drake/scene", "/drake/proximity/scene"
TRANSFORMS, PROXIMITY_TRANSFORMS = "/drake/transforms", "/drake/proximity/transforms"
CAMERA_IMAGES = ("/drake/cameras/wrist/color/image", "/drake/cameras/wrist/depth/image")
# lcmt_iiwa_status's first three floating-point fields in its field order, each array by its first joint
IIWA_PLOTS = (
    "/lcm/IIWA_STATUS.joint_position_measured[0]",
    "/lcm/IIWA_STATUS.joint_velocity_estimated[0]",
    "/lcm/IIWA_STATUS.joint_position_commanded[0]",
)


def layout_command(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "viewer_bridge.cli.main", "layout", *args],
                          capture_output=True, text=True, timeout=300, check=False)  # fmt: skip


@pytest.fixture(scope="module")
def drake_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    scene = demo_scene()
    load, draw = load_from_scene(scene).encode(), DrawEncoder().encode(demo_poses(scene, 0.5))
    pixels = np.zeros((4, 6, 4), np.uint8), np.full((4, 6, 1), 1000, np.uint16)
    images = publish_with_drake([("color", "rgba8", pixels[0]), ("depth", "depth16", pixels[1])], 0.5, False)
    t0 = 1_700_000_000_000_000
    events = [
        LcmEvent("DRAKE_VIEWER_LOAD_ROBOT", load, t0),
        LcmEvent("DRAKE_VIEWER_LOAD_ROBOT_PROXIMITY", load, t0 + 1),
        LcmEvent("DRAKE_VIEWER_DRAW", draw, t0 + 10),
        LcmEvent("DRAKE_VIEWER_DRAW_PROXIMITY", draw, t0 + 11),
        LcmEvent("DRAKE_RGBD_CAMERA_IMAGES_wrist", images, t0 + 20),
        LcmEvent("IIWA_STATUS", iiwa_status(0.5).encode(), t0 + 30),
        LcmEvent("MYSTERY", bytes(range(40)), t0 + 40),
        LcmEvent("DRAKE_VIEWER_DRAW", draw, t0 + 50),
    ]
    path = tmp_path_factory.mktemp("layout") / "drake.lcmlog"
    write_log(path, events)
    return path


def panels(node: Any) -> list[dict[str, Any]]:
    """Every panel of a layout's JSON, depth first, whatever containers hold them."""
    if isinstance(node, dict):
        if node.get("type") == "panel":
            return [node]
        return [panel for value in node.values() for panel in panels(value)]
    if isinstance(node, list):
        return [panel for value in node for panel in panels(value)]
    return []


def test_a_logs_layout_has_the_scene_in_world_each_camera_image_and_a_plot_of_its_lcm_fields(
    drake_log: Path, tmp_path: Path
) -> None:
    out = tmp_path / "drake-layout.json"
    done = layout_command(str(drake_log), "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "MYSTERY" in done.stderr and "left out" in done.stderr  # said, and the rest laid out
    written = json.loads(out.read_text())
    expected = LayoutTopics(
        scenes=(SCENE, PROXIMITY_SCENE),
        hidden_scenes=frozenset({PROXIMITY_SCENE}),  # illustration shown, proximity listed and off
        transforms=(TRANSFORMS, PROXIMITY_TRANSFORMS),
        images=CAMERA_IMAGES,
        plots=IIWA_PLOTS,
        frame="world",
    )
    assert written == json.loads(foxglove_layout(expected).to_json())  # foxglove.layouts' own serialisation
    by_type: dict[str, list[dict[str, Any]]] = {}
    for panel in panels(written):
        by_type.setdefault(panel["panelType"], []).append(panel)
    assert sorted(by_type) == ["Image", "Plot", "ThreeDee"]
    (three_d,) = by_type["ThreeDee"]
    assert three_d["config"]["followTf"] == "world"
    assert three_d["config"]["topics"] == {
        SCENE: {"visible": True},
        PROXIMITY_SCENE: {"visible": False},
        TRANSFORMS: {"visible": True},
        PROXIMITY_TRANSFORMS: {"visible": True},
    }
    assert [panel["config"]["imageMode"]["imageTopic"] for panel in by_type["Image"]] == list(CAMERA_IMAGES)
    (plot,) = by_type["Plot"]
    assert [series["value"] for series in plot["config"]["paths"]] == list(IIWA_PLOTS)


def test_with_no_log_the_layout_is_the_default_channels_scene_and_an_empty_plot(tmp_path: Path) -> None:
    out = tmp_path / "layout.json"
    done = layout_command("--out", str(out))
    assert done.returncode == 0, done.stderr
    assert "Layouts > Import from file" in done.stderr
    expected = LayoutTopics(scenes=(SCENE,), transforms=(TRANSFORMS,))
    assert json.loads(out.read_text()) == json.loads(foxglove_layout(expected).to_json())
    assert [panel["panelType"] for panel in panels(json.loads(out.read_text()))] == ["ThreeDee", "Plot"]


def test_a_config_without_foxglove_routes_and_an_empty_log_are_one_line_and_exit_2(tmp_path: Path) -> None:
    config = tmp_path / "ros_only.yaml"
    config.write_text(
        "routes:\n  - name: tf\n    source: {transport: lcm, name: DRAKE_VIEWER_DRAW}\n"
        "    translator: drake_to_tf\n    destination: {transport: ros, name: /tf}\n"
    )
    done = layout_command("--out", str(tmp_path / "a.json"), "-c", str(config))
    assert done.returncode == 2 and "writes to Foxglove" in done.stderr and len(done.stderr.splitlines()) == 1
    empty = tmp_path / "empty.lcmlog"
    empty.write_bytes(b"")
    done = layout_command(str(empty), "--out", str(tmp_path / "a.json"))
    assert done.returncode == 2 and "no whole LCM event" in done.stderr and len(done.stderr.splitlines()) == 1
    assert not (tmp_path / "a.json").exists()


def test_the_plot_takes_floats_first_each_array_by_its_first_element() -> None:
    message = {"utime": 5, "count": 2, "flag": True, "name": "x", "position": [0.5, 0.25],
               "nested": {"gain": 1.5, "empty": []}, "bytes": {"base64": "AA=="}, "rows": [{"v": 2.0}]}  # fmt: skip
    assert numeric_paths(message) == [".position[0]", ".nested.gain", ".rows[0].v"]
    assert numeric_paths({"utime": 5, "count": 2}) == [".utime", ".count"]  # no float: the integers
    assert numeric_paths({"a": [], "b": "text"}) == []
