"""Contact results: Drake's message -> neutral contacts -> ROS 2 markers and wrenches, checked
against pydrake's own `lcmt_contact_results_for_viz` class and a real pydrake simulation (the
message itself: tests/formats/drake/test_contact.py)."""

from __future__ import annotations

import io
import subprocess
import sys
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest

from tests.conftest import EXAMPLES, lcm_url
from tests.formats.drake.test_contact import pydrake_results
from tests.formats.ros.oracle import ARROW, DELETEALL, TRIANGLE_LIST
from tests.peers import BridgeProcess, RosProbe
from tests.test_router import LcmRecorder
from viewer_bridge.examples.scenes import demo_contact_results
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY
from viewer_bridge.formats.ros.messages import from_cdr
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.formats.tree_viewer.tree import TreeState
from viewer_bridge.model.contact import FORCE_COLOR, pressure_colors
from viewer_bridge.model.scene import Line, Scene, TriangleMesh
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import Received

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)

CONTACT_SCENE_SCRIPT = EXAMPLES / "contacts.py"


# --- end to end: pydrake -> bridge process -> rclpy ---------------------------------------------------


def fan(poly_data: list[int]) -> list[int]:
    """The vertex indices of Drake's polygons as triangle fans, three per triangle."""
    corners, offset = [], 0
    while offset < len(poly_data):
        count = poly_data[offset]
        polygon = poly_data[offset + 1 : offset + 1 + count]
        for k in range(1, count - 1):
            corners += [polygon[0], polygon[k], polygon[k + 1]]
        offset += 1 + count
    return corners


def _arrow_starts(markers: list[Any]) -> list[list[float]]:
    """Where each force arrow of a MarkerArray starts (Drake's contact point or centroid)."""
    return [[m.points[0].x, m.points[0].y, m.points[0].z] for m in markers if m.ns == "contact/forces"]


@pytest.mark.slow
def test_a_drake_simulation_reaches_ros_as_contact_markers_and_wrenches() -> None:
    probe = RosProbe("contact_probe")
    url = lcm_url(15)
    markers = probe.subscribe(
        "/drake/contacts/markers", "visualization_msgs/msg/MarkerArray", 100, latched=True
    )
    wrenches = probe.subscribe("/drake/contacts/wrenches", "geometry_msgs/msg/WrenchStamped", 1000)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--lcm-url", url, "--stats-period", "1")
    try:
        bridge.wait_for_line(" running (")
        subprocess.run(
            [sys.executable, str(CONTACT_SCENE_SCRIPT), url, "0.5", "1.0"], check=True, timeout=120
        )
        recorder.sync()  # holds the simulation's last contact results
        last = drake_lcmtypes.lcmt_contact_results_for_viz.decode(recorder.messages["CONTACT_RESULTS"][-1])
        pairs = last.num_point_pair_contacts + last.num_hydroelastic_contacts
        expected_forces = [list(p.contact_force) for p in last.point_pair_contact_info] + [
            list(h.force_C_W) for h in last.hydroelastic_contacts
        ]

        def last_wrenches() -> list[list[float]]:
            return [[w.wrench.force.x, w.wrench.force.y, w.wrench.force.z] for w in list(wrenches)[-pairs:]]

        expected_starts = [list(p.contact_point) for p in last.point_pair_contact_info] + [
            list(h.centroid_W) for h in last.hydroelastic_contacts
        ]
        assert probe.wait_for(lambda: last_wrenches() == expected_forces)
        # The last MarkerArray is published beside the last wrenches.
        assert probe.wait_for(lambda: bool(markers) and _arrow_starts(markers[-1].markers) == expected_starts)
    finally:
        assert bridge.stop() == 0
        recorder.close()
        probe.close()
    assert last.num_point_pair_contacts >= 1 and last.num_hydroelastic_contacts == 1  # both kinds happened
    assert all(w.header.frame_id == "world" for w in wrenches)
    torques = [[w.wrench.torque.x, w.wrench.torque.y, w.wrench.torque.z] for w in wrenches[-pairs:]]
    assert torques[-1] == list(last.hydroelastic_contacts[0].moment_C_W)
    # The last MarkerArray: a force arrow per pair from Drake's point (centroid), the surface's vertices.
    array = markers[-1].markers
    assert array[0].action == DELETEALL
    assert _arrow_starts(array) == expected_starts
    for marker, force in zip([m for m in array if m.ns == "contact/forces"], expected_forces, strict=True):
        assert marker.type == ARROW
        end, start = marker.points[1], marker.points[0]
        assert np.allclose([end.x - start.x, end.y - start.y, end.z - start.z], np.array(force) * 0.01)
    surface_message = last.hydroelastic_contacts[0]
    (surface,) = [m for m in array if m.type == TRIANGLE_LIST]
    vertices = [[p.x, p.y, p.z] for p in surface_message.p_WV]
    assert [[p.x, p.y, p.z] for p in surface.points] == [
        vertices[i] for i in fan(list(surface_message.poly_data))
    ]
    assert len(surface.colors) == len(surface.points)


def test_dump_decodes_contact_results() -> None:
    from viewer_bridge.cli.dump import as_text, describe
    from viewer_bridge.transports.lcm import LcmEvent

    event = LcmEvent("CONTACT_RESULTS", pydrake_results().encode(), 5)
    record = describe(event)
    assert record["type"] == "drake.lcmt_contact_results_for_viz" and "error" not in record
    surface = record["message"]["hydroelastic_contacts"][0]
    # ROS 2 names
    assert surface["p_wv"][4] == {"x": 0.02, "y": 0.005, "z": 0.0} and surface["poly_data"][0] == 4
    assert "  point_pair_contact_info[1]:" in as_text(event).splitlines()


def test_tree_viewer_gets_arrows_as_lines_with_heads() -> None:
    translator = TRANSLATORS.get("drake_contacts_to_tree_viewer")({"force_scale": 0.1})
    out = translator.translate(Received("CONTACT_RESULTS", pydrake_results().encode()))
    requests = [envelope.decode(data) for _, data in out]
    assert requests[0]["delete"] == [{"path": ["contacts"]}]
    state = TreeState()
    for request in requests:
        assert state.apply(request)["status"] == envelope.OK
    links = {link.name: link for link in state.scene().links}
    forces = [g.shape for g in links["contact::forces"].geometries]
    assert all(isinstance(line, Line) and line.end_head and not line.start_head for line in forces)
    assert np.allclose(forces[0].points, [[0.0, 0.2, -1e-5], [0.05, 0.175, 0.981 - 1e-5]], rtol=0, atol=1e-12)
    (surface,) = links["contact::surfaces"].geometries
    assert isinstance(surface.shape, TriangleMesh) and len(surface.shape.triangles) == 3
    assert surface.color != (1.0, 1.0, 1.0, 1.0)  # the pressure colour of its mean pressure


def test_snapshot_draws_arrows_and_pressure_bands() -> None:
    from PIL import Image

    from viewer_bridge.render.snapshot import snapshot, with_contacts

    results = demo_contact_results(4, (20, 20))
    scene = with_contacts(Scene(), results)
    kinds = {type(g.shape).__name__ for link in scene.links for g in link.geometries}
    assert kinds == {"TriangleMesh"}  # arrows tessellated, surfaces split into colour bands
    picture = Image.open(io.BytesIO(snapshot(scene, 320, 240, image="label")))
    colours = {tuple(pixel) for pixel in np.asarray(picture).reshape(-1, 3).tolist()}
    assert tuple(round(255 * c) for c in FORCE_COLOR[:3]) in colours  # an arrow, unlit
    ramp = {tuple(round(255 * c) for c in row) for row in pressure_colors(np.linspace(0, 1, 16), 0, 1)}
    assert len(colours & ramp) >= 4  # the surface in several pressure bands


def test_marker_options_reach_the_table_and_unknown_ones_are_refused() -> None:
    options = {"frame_id": "map", "force_scale": 0.5, "pressure_range": [0, 1e6], "surfaces": False}
    translator = TRANSLATORS.get("drake_contacts_to_marker_array")(options)
    ((_, data),) = translator.translate(Received("CONTACT_RESULTS", pydrake_results().encode()))
    markers = from_cdr(data, MARKER_ARRAY).markers
    assert {m.header.frame_id for m in markers[1:]} == {"map"}
    assert not [m for m in markers if m.type == TRIANGLE_LIST]
    force = markers[1]
    assert force.points[1].z - force.points[0].z == pytest.approx(0.5 * 9.81)
    with pytest.raises(ValueError, match="force_scael"):
        TRANSLATORS.get("drake_contacts_to_marker_array")({"force_scael": 1})
