"""Extension points: a transport and a translator from a plugin package installed into the venv.

The plugin (tests/plugin_package) is an ordinary pip-installable package whose entry points name
an in-memory transport and a draw -> JSON translator; nothing in `bridge/` knows it. A real
Drake draw (encoded by pydrake's own `lcmt_viewer_draw`) goes through it, both with the plugin's
translator and with a built-in one over the plugin's transport.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest

from viewer_bridge.config.bridge import load_config
from viewer_bridge.formats.ros.poses import pose_array_arrays
from viewer_bridge.router.router import Router
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.registry import TRANSPORTS

PLUGIN = Path(__file__).parent / "plugin_package"

CONFIG = """\
memory: {bus: plugin-test}
routes:
  - name: json
    source: {transport: memory, name: "DRAKE_VIEWER_DRAW(_[A-Z]+)?"}
    translator: drake_draw_to_json
    destination: {transport: memory, name: "/json{1:path}"}
    rate: {policy: all}
    options: {digits: 5}
  - name: poses
    source: {transport: memory, name: "DRAKE_VIEWER_DRAW(_[A-Z]+)?"}
    translator: drake_to_pose_array
    destination: {transport: memory, name: "/poses{1:path}"}
    rate: {policy: all}
time: sim  # the PoseArray stamped with the draw's sim time
"""


def _pip(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args], check=True)


@pytest.fixture(scope="module")
def plugin_installed() -> Iterator[None]:
    # Offline, from the source folder, with the venv's own hatchling (a test extra).
    _pip("install", "--no-deps", "--no-build-isolation", "--no-index", str(PLUGIN))
    try:
        yield
    finally:
        _pip("uninstall", "-y", "viewer-bridge-example-plugin")


def drake_draw(timestamp_ms: int) -> bytes:
    message = drake_lcmtypes.lcmt_viewer_draw()
    message.timestamp = timestamp_ms
    message.num_links = 2
    message.link_name = ["plant::iiwa::link_1", "plant::iiwa::link_2"]
    message.robot_num = [2, 2]
    message.position = [[0.5, -0.25, 1.0], [0.0, 0.125, 2.0]]
    message.quaternion = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    return bytes(message.encode())


def test_a_plugin_transport_and_translator_carry_a_drake_draw(plugin_installed: None, tmp_path: Path) -> None:
    assert "memory" in TRANSPORTS.names() and "drake_draw_to_json" in TRANSLATORS.names()
    path = tmp_path / "plugin.yaml"
    path.write_text(CONFIG)
    router = Router(load_config(path))
    router.start()
    bus: Any = TRANSPORTS.get("memory").buses["plugin-test"]  # type: ignore[attr-defined]
    try:
        bus.inject("DRAKE_VIEWER_DRAW_PROXIMITY", drake_draw(1234))
        published = bus.wait_for(2)
    finally:
        router.close()
    by_name = {name: (typename, data) for name, typename, data in published}
    assert set(by_name) == {"/json/proximity", "/poses/proximity"}
    typename, data = by_name["/json/proximity"]
    assert typename == "viewer_bridge_example/DrawJson"
    assert json.loads(data) == {
        "timestamp_ms": 1234,
        "links": {
            "plant::iiwa::link_1": [0.5, -0.25, 1.0, 1.0, 0.0, 0.0, 0.0],
            "plant::iiwa::link_2": [0.0, 0.125, 2.0, 0.0, 0.0, 0.0, 1.0],
        },
    }
    typename, data = by_name["/poses/proximity"]
    assert typename == "geometry_msgs/msg/PoseArray"
    stamp_ms, frame_id, positions, xyzw = pose_array_arrays(data)
    assert (stamp_ms, frame_id) == (1234, "world")
    assert np.array_equal(positions, [[0.5, -0.25, 1.0], [0.0, 0.125, 2.0]])
    assert np.array_equal(xyzw, [[0, 0, 0, 1.0], [0, 0, 1.0, 0]])
    stats = router.snapshot()["routes"]
    assert stats["json"]["errors"] == {} and stats["poses"]["messages_out"] == 1


def test_plugin_options_are_checked_at_load(plugin_installed: None, tmp_path: Path) -> None:
    from viewer_bridge.errors import ConfigError

    path = tmp_path / "plugin.yaml"
    path.write_text(CONFIG.replace("{digits: 5}", "{digits: five}"))
    with pytest.raises(ConfigError, match=r"plugin.yaml:8: routes.0.options.digits: .*valid integer"):
        load_config(path)
    path.write_text(CONFIG.replace("bus: plugin-test", "bus: plugin-test, colour: red"))
    with pytest.raises(
        ConfigError, match=r"plugin.yaml:1: memory.colour: unknown key 'colour'; known keys: "
    ):
        load_config(path)
