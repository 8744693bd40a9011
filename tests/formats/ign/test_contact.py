"""Contact results as ign/gz `Contacts` (through their translator), read back with protoc's classes
for Debian's ign-msgs 8 files."""

from __future__ import annotations

from types import ModuleType

from tests.formats.drake.test_contact import pydrake_results
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import Received


def test_ign_contacts_read_by_debians_protos(debian_ign_msgs: ModuleType) -> None:
    translator = TRANSLATORS.get("drake_contacts_to_ign_contacts")({})
    assert translator.outputs[0].type.name == "Contacts"  # in the ign transport's package
    ((_, data),) = translator.translate(Received("CONTACT_RESULTS", pydrake_results().encode()))
    theirs = debian_ign_msgs.Contacts.FromString(data)
    assert (theirs.header.stamp.sec, theirs.header.stamp.nsec) == (1, 234_567_000)
    assert len(theirs.contact) == 3
    point, _, surface = theirs.contact
    assert (point.collision1.name, point.collision2.name, point.world.name) == (
        "world(0)",
        "box0(1)",
        "world",
    )
    assert point.collision1.type == debian_ign_msgs.Entity.LINK
    assert [(p.x, p.y, p.z) for p in point.position] == [(0.0, 0.2, -1e-5)]
    assert [(n.x, n.y, n.z) for n in point.normal] == [(0.0, 0.0, 1.0)]
    (wrench,) = point.wrench
    body2 = wrench.body_2_wrench.force  # Drake's point force acts on body 2
    assert (wrench.body_2_name, body2.x, body2.y, body2.z) == ("box0(1)", 0.5, -0.25, 9.81)
    assert wrench.body_1_wrench.force.z == -9.81
    (surface_wrench,) = surface.wrench
    assert surface.position[0].x == 0.5 and surface_wrench.body_1_wrench.force.z == -9.4
    assert surface_wrench.body_1_wrench.torque.x == 0.01 and surface_wrench.body_2_wrench.torque.y == -0.02
    gz = TRANSLATORS.get("drake_contacts_to_ign_contacts")({"package": "gz"})
    assert gz.outputs[0].type.name == "gz.msgs.Contacts"
