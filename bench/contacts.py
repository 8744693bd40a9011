"""Benchmark: contact results -> visualization_msgs/MarkerArray CDR, beside the rclpy way, in this process.

Run: .venv/bin/python bench/contacts.py [--points 1000] [--grid 100 50] [--budget 0.5]

The message: `--points` point contacts and one hydroelastic surface of rows x columns x 2
triangles (100 x 50 x 2 = 10,000 by default), as Drake's `lcmt_contact_results_for_viz` bytes.
Ours: `decode_contact_results` (the generated LCM codec, polygon checks) -> `contact_scene`
(arrows, pressure colours) -> the marker table's CDR fast path. Baseline: the same bytes decoded
by Drake's own Python class (`drake.lcmt_contact_results_for_viz`), then rclpy
`visualization_msgs` objects built one by one (a Marker per arrow, a Point and a ColorRGBA per
surface corner) and `rclpy.serialization.serialize_message`. Both give the same markers (checked).
"""

from __future__ import annotations

import argparse
from typing import Any

import drake as drake_lcmtypes
import numpy as np
from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import seconds_per_call
from geometry_msgs.msg import Point
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from tests.formats.drake.oracle import contact_results_to_lcm
from viewer_bridge.examples.scenes import demo_contact_results
from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.ros.contact import contact_marker_array_cdr
from viewer_bridge.model.contact import (
    FORCE_COLOR,
    MOMENT_COLOR,
    ContactDrawOptions,
    pressure_colors,
)


def _arrow(
    ns: str, marker_id: int, start: list[float], vector: list[float], scale: float, color: Any
) -> Marker:
    radius = ContactDrawOptions().arrow_radius
    marker = Marker(ns=ns, id=marker_id, type=Marker.ARROW, action=Marker.ADD)
    marker.header.frame_id = "world"
    marker.pose.orientation.w = 1.0
    marker.points = [Point(x=start[0], y=start[1], z=start[2]),
                     Point(x=start[0] + vector[0] * scale, y=start[1] + vector[1] * scale,
                           z=start[2] + vector[2] * scale)]  # fmt: skip
    marker.scale.x, marker.scale.y, marker.scale.z = 2 * radius, 5 * radius, 5 * radius
    marker.color = ColorRGBA(r=color[0], g=color[1], b=color[2], a=color[3])
    return marker


def rclpy_markers(data: bytes) -> bytes:
    """The baseline: Drake's class decodes, rclpy objects are built one by one, then serialised."""
    message = drake_lcmtypes.lcmt_contact_results_for_viz.decode(data)
    options = ContactDrawOptions()
    markers = [Marker(action=Marker.DELETEALL)]
    pairs = [(p.contact_point, p.contact_force) for p in message.point_pair_contact_info]
    pairs += [(h.centroid_W, h.force_C_W) for h in message.hydroelastic_contacts]
    for index, (point, force) in enumerate(pairs):
        markers.append(_arrow("contact/forces", index, point, force, options.force_scale, FORCE_COLOR))
    for index, h in enumerate(message.hydroelastic_contacts):
        markers.append(_arrow("contact/moments", index, h.centroid_W, h.moment_C_W, options.moment_scale,
                              MOMENT_COLOR))  # fmt: skip
    highest = max((max(h.pressure) for h in message.hydroelastic_contacts), default=0.0)
    for index, h in enumerate(message.hydroelastic_contacts):
        surface = Marker(ns="contact/surfaces", id=index, type=Marker.TRIANGLE_LIST, action=Marker.ADD)
        surface.header.frame_id = "world"
        surface.pose.orientation.w = 1.0
        surface.scale.x = surface.scale.y = surface.scale.z = 1.0
        surface.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
        colours = pressure_colors(np.asarray(h.pressure), 0.0, highest).tolist()
        points, colors, offset, poly = [], [], 0, h.poly_data
        while offset < len(poly):
            count = poly[offset]
            corners = poly[offset + 1 : offset + 1 + count]
            for k in range(1, count - 1):
                for vertex in (corners[0], corners[k], corners[k + 1]):
                    p = h.p_WV[vertex]
                    points.append(Point(x=p.x, y=p.y, z=p.z))
                    r, g, b = colours[vertex]
                    colors.append(ColorRGBA(r=r, g=g, b=b, a=1.0))
            offset += 1 + count
        surface.points, surface.colors = points, colors
        markers.append(surface)
    return bytes(serialize_message(MarkerArray(markers=markers)))


def _same(ours: bytes, theirs: bytes) -> None:
    a, b = deserialize_message(ours, MarkerArray).markers, deserialize_message(theirs, MarkerArray).markers
    assert [(m.ns, m.id, m.type, m.action) for m in a] == [(m.ns, m.id, m.type, m.action) for m in b]
    for x, y in zip(a, b, strict=True):
        assert [(p.x, p.y, p.z) for p in x.points] == [(p.x, p.y, p.z) for p in y.points]
        assert np.allclose(
            [(c.r, c.g, c.b) for c in x.colors], [(c.r, c.g, c.b) for c in y.colors], atol=1e-6
        )


def measures(size: Size = Size.FULL) -> list[Measure]:
    """Issue 13: 1000 point contacts and a 10,000-triangle surface -> MarkerArray CDR."""
    data = contact_results_to_lcm(demo_contact_results(1000, (100, 50), 1_000_000)).encode()
    budget = size.pick(full=0.5, quick=0.2, smoke=0.0)
    ours = seconds_per_call(lambda: contact_marker_array_cdr(decode_contact_results(data)), budget)
    baseline = seconds_per_call(lambda: rclpy_markers(data), budget)
    return [Measure("contact results (1000 points, 10,000-triangle surface) -> MarkerArray CDR",
                    ours * 1e3, baseline * 1e3, "ms", "faster than rclpy objects", ours < baseline)]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--points", type=int, default=1000)
    parser.add_argument("--grid", type=int, nargs=2, default=[100, 50], metavar=("ROWS", "COLUMNS"))
    parser.add_argument("--budget", type=float, default=0.5, help="seconds per measurement")
    args = parser.parse_args()

    results = demo_contact_results(args.points, tuple(args.grid), 1_000_000)
    data = contact_results_to_lcm(results).encode()
    triangles = len(results.hydroelastic[0].surface.triangles)

    def ours() -> bytes:
        return contact_marker_array_cdr(decode_contact_results(data))

    def baseline() -> bytes:
        return rclpy_markers(data)

    _same(ours(), baseline())
    fast, slow = seconds_per_call(ours, args.budget), seconds_per_call(baseline, args.budget)
    decode = seconds_per_call(lambda: decode_contact_results(data), args.budget)
    print(f"contact results -> MarkerArray CDR: {args.points} point contacts, a {triangles}-triangle surface "
          f"({len(data) / 1e6:.2f} MB of LCM)")  # fmt: skip
    print(f"  viewer-bridge (decode {decode * 1e3:.1f} ms)      {fast * 1e3:10.1f} ms")
    print(f"  pydrake decode + rclpy objects + serialize {slow * 1e3:10.1f} ms")
    print(f"  ratio                                      {slow / fast:10.1f}x")


if __name__ == "__main__":
    main()
