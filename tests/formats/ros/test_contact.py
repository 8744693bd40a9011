"""Contact results as ROS 2 markers (arrows, pressure-coloured surfaces) and wrenches, from pydrake's
own `lcmt_contact_results_for_viz` class."""

from __future__ import annotations

import numpy as np

from tests.formats.drake.test_contact import pydrake_results
from tests.formats.ros import oracle as ros_oracle
from tests.formats.ros.oracle import ARROW, DELETEALL, TRIANGLE_LIST
from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.ros.contact import WrenchEncoder, contact_marker_array_cdr
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY, WRENCH_STAMPED
from viewer_bridge.formats.ros.messages import from_cdr, to_cdr
from viewer_bridge.model.contact import ContactDrawOptions, pressure_colors
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import Received


def test_markers_arrows_and_pressure_coloured_surface() -> None:
    results = decode_contact_results(pydrake_results().encode())
    draw = ContactDrawOptions(force_scale=0.1, moment_scale=2.0, pressure_range=(0.0, 4e5))
    data = contact_marker_array_cdr(results, draw)
    markers = from_cdr(data, MARKER_ARRAY).markers
    assert to_cdr(ros_oracle.contact_marker_array(results, draw)) == data  # the object path agrees
    assert markers[0].action == DELETEALL
    arrows = [m for m in markers if m.type == ARROW]
    forces = [m for m in arrows if m.ns == "contact/forces"]
    assert len(forces) == 3 and len([m for m in arrows if m.ns == "contact/moments"]) == 1
    start, end = forces[0].points
    assert [start.x, start.y, start.z] == [0.0, 0.2, -1e-5]
    assert np.allclose([end.x - start.x, end.y - start.y, end.z - start.z], [0.05, -0.025, 0.981])
    (surface,) = [m for m in markers if m.type == TRIANGLE_LIST]
    vertices = results.hydroelastic[0].surface.vertices
    assert [[p.x, p.y, p.z] for p in surface.points] == vertices[[0, 1, 2, 0, 2, 3, 1, 4, 2]].tolist()
    colours = np.array([[c.r, c.g, c.b, c.a] for c in surface.colors])
    assert colours[0].tolist() == [0, 0, 1, 1] and colours[-2].tolist() == [1, 0, 0, 1]  # 0 Pa blue, 4e5 red
    assert np.allclose(colours[:, :3], pressure_colors(np.array([0.0, 1, 2, 0, 2, 3, 1, 4, 2]) * 1e5, 0, 4e5))


def test_wrenches_one_per_pair() -> None:
    results = decode_contact_results(pydrake_results().encode())
    wrenches = [from_cdr(data, WRENCH_STAMPED) for data in WrenchEncoder("map").encode(results, (3, 5))]
    assert len(wrenches) == 3
    assert all(
        (w.header.frame_id, w.header.stamp.sec, w.header.stamp.nanosec) == ("map", 3, 5) for w in wrenches
    )
    assert [[w.wrench.force.x, w.wrench.force.y, w.wrench.force.z] for w in wrenches] == [
        [0.5, -0.25, 9.81], [0.5, -0.25, 9.81], [0.0, 0.0, -9.4]]  # fmt: skip
    assert [w.wrench.torque.x for w in wrenches] == [0.0, 0.0, 0.01]
    sim = TRANSLATORS.get("drake_contacts_to_wrenches")({"stamp": "sim"})
    out = sim.translate(Received("CONTACT_RESULTS", pydrake_results().encode()))
    stamp = from_cdr(out[0][1], WRENCH_STAMPED).header.stamp
    assert (stamp.sec, stamp.nanosec) == (1, 234_567_000)
