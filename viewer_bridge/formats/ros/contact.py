"""Contact results to ROS 2: a `visualization_msgs/MarkerArray` to look at, `geometry_msgs/WrenchStamped`s
for controllers.

The markers are the contact scene (`viewer_bridge.model.contact.contact_scene`) written by the marker table
(`mappings/ros.yaml`): an ARROW per force and per moment, a TRIANGLE_LIST per hydroelastic
surface with a colour per vertex. The array starts with DELETEALL, so contacts that ended vanish.

A WrenchStamped per contact pair, point contacts first, then hydroelastic ones, in Drake's
order: the force (and for hydroelastic contacts the moment) exactly as Drake sends them, in
world axes (`frame_id`); a point contact's force acts on body 2 at the contact point, a
hydroelastic one's on body 1 at the surface's centroid (WrenchStamped has no application point).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from viewer_bridge.formats.ros.cdr import StampedTemplate
from viewer_bridge.formats.ros.markers import marker_array_cdr
from viewer_bridge.model.contact import ContactDrawOptions, ContactResults, contact_scene


def contact_marker_array_cdr(
    results: ContactResults, draw: ContactDrawOptions | None = None, markers: dict[str, Any] | None = None
) -> bytes:
    """The contacts as MarkerArray CDR (DELETEALL first); `markers` overrides the marker table's options."""
    return marker_array_cdr(contact_scene(results, draw), markers, delete_all=True)


def contact_wrenches(results: ContactResults) -> np.ndarray[Any, Any]:
    """P x 6 rows (force x y z, torque x y z), one per contact pair in the order described above."""
    point = np.concatenate((results.point.forces, np.zeros_like(results.point.forces)), axis=1)
    hydroelastic = [np.concatenate((c.force, c.moment)) for c in results.hydroelastic]
    return np.concatenate((point, np.array(hydroelastic).reshape(-1, 6)))


_NO_WRENCH = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


class WrenchEncoder:
    """One WrenchStamped CDR per contact pair, all in `frame_id`: written once, then each call's
    stamp and each pair's six numbers where the writer marked them.

    Raises `EncodeError` for a frame id that is no CDR string.
    """

    def __init__(self, frame_id: str = "world") -> None:
        self._template = StampedTemplate(
            "geometry_msgs/msg/WrenchStamped", (((0, 0), frame_id), _NO_WRENCH), ("wrench",)
        )
        self._wrench_at = self._template.at["wrench"]  # the wrench, 6 float64, ends the message

    def encode(self, results: ContactResults, stamp: tuple[int, int]) -> list[bytes]:
        header = self._template.stamped(stamp)[: self._wrench_at]
        rows = np.ascontiguousarray(contact_wrenches(results), dtype="<f8")
        return [header + row.tobytes() for row in rows]
