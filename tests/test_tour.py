"""The README's tour as a new user meets it: the demo's log replayed to ROS 2 (step 3), a
subscriber started first; and the first load's meshes not made late by importing trimesh."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.peers import BridgeProcess, RosProbe
from viewer_bridge.transports.lcm import read_log

pytestmark = [pytest.mark.slow, pytest.mark.e2e]


def test_a_replay_of_the_tours_log_reaches_a_subscriber_started_before_it(tmp_path: Path) -> None:
    log = tmp_path / "demo.lcmlog"
    subprocess.run([sys.executable, "-m", "viewer_bridge.cli.main", "demo", "--url", f"file://{log}?mode=w",
                    "--duration", "3"], check=True, timeout=120, capture_output=True)  # fmt: skip
    draws = len(list(read_log(log, "DRAKE_VIEWER_DRAW")))
    stats = tmp_path / "stats.json"
    probe = RosProbe("tour")
    try:
        tf = probe.subscribe("/tf", "tf2_msgs/msg/TFMessage")
        markers = probe.subscribe("/drake/markers", "visualization_msgs/msg/MarkerArray")
        link_markers = probe.subscribe(
            "/drake/link_markers", "visualization_msgs/msg/MarkerArray", latched=True
        )
        bridge = BridgeProcess("--lcm-url", f"file://{log}?speed=1", "--stats-json", str(stats))
        assert bridge.process.wait(timeout=180) == 0, "\n".join(bridge.lines)
        routes = json.loads(stats.read_text())["routes"]
        assert routes["tf"]["messages_in"] >= draws
        # The lazy routes saw the subscriber and sent (what DDS delivers of the first ones, while
        # the subscriber is still matching the bridge's new publisher, is DDS's: at most a few).
        for topic, route in ((tf, "tf"), (markers, "markers")):
            half = routes[route]["messages_out"] // 2
            assert probe.wait_for(lambda got=topic, half=half: len(got) >= half > 0, timeout=30), routes[
                route
            ]
        assert probe.wait_for(lambda: len(link_markers) == 1)  # the scene, latched, once per load
    finally:
        probe.close()


IMPORTS = """
import sys
from viewer_bridge import convert
assert "trimesh" not in sys.modules, "importing the converters imports trimesh"
from viewer_bridge.translators.registry import TRANSLATORS
TRANSLATORS["drake_to_shapes"]({})
assert "trimesh" in sys.modules, "a translator of scenes is made without trimesh"
"""


def test_trimesh_is_imported_when_a_scene_translator_is_made_not_by_its_first_load() -> None:
    """Imported on the first load, trimesh (with scipy: 1 to 2.5 s on a busy core) made the demo's
    `shapes` latency about 1.5 s and every other route supersede a second of draws."""
    result = subprocess.run([sys.executable, "-c", IMPORTS], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
