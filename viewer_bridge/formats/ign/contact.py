"""Contact results to ign/gz `Contacts`: one `Contact` per contact pair.

Field numbers from Debian's ign-msgs 8 protos (contacts.proto, contact.proto, joint_wrench.proto,
wrench.proto, entity.proto), declared in `viewer_bridge.formats.ign.schema`. Each Contact names its two
bodies (`collision1`/`collision2`, LINK entities named by Drake's body names), has one
`position` (the contact point, or a surface's centroid), one `normal` (a point contact's; for a
surface, the direction of its force), `depth` 0 (Drake does not send penetration depth), and one
`JointWrench` whose `body_1_wrench` and `body_2_wrench` are equal and opposite: a point contact's
force acts on body 2, a surface's force and moment on body 1 (Drake's conventions). World axes;
`world` names the world entity.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.model.contact import ContactResults
from viewer_bridge.model.scene import FloatArray

_LINK = 3  # Entity.Type.LINK


def contacts_message(results: ContactResults, world: str = "world") -> Any:
    """The results as a `Contacts` message, stamped with Drake's sim time."""
    message = MESSAGES.Contacts()
    seconds, microseconds = divmod(int(results.timestamp_us), 1_000_000)
    message.header.stamp.sec, message.header.stamp.nsec = seconds, microseconds * 1000
    point = results.point
    for (body1, body2), position, force, normal in zip(
        point.body_pairs, point.points, point.forces, point.normals, strict=True
    ):
        zero = np.zeros(3)
        _add_contact(message, world, (body1, body2), position, normal, on_body_1=(-force, zero))
    for contact in results.hydroelastic:
        length = float(np.linalg.norm(contact.force))
        direction = contact.force / length if length > 0 else np.zeros(3)
        names = (contact.body1.body, contact.body2.body)
        _add_contact(
            message, world, names, contact.centroid, direction, on_body_1=(contact.force, contact.moment)
        )
    return message


def _add_contact(
    message: Any,
    world: str,
    names: tuple[str, str],
    position: FloatArray,
    normal: FloatArray,
    on_body_1: tuple[FloatArray, FloatArray],
) -> None:
    contact = message.contact.add()
    contact.collision1.name, contact.collision1.type = names[0], _LINK
    contact.collision2.name, contact.collision2.type = names[1], _LINK
    contact.world.name = world
    _set(contact.position.add(), position)
    _set(contact.normal.add(), normal)
    contact.depth.append(0.0)
    wrench = contact.wrench.add()
    wrench.body_1_name, wrench.body_2_name = names
    force, torque = on_body_1
    _set(wrench.body_1_wrench.force, force)
    _set(wrench.body_1_wrench.torque, torque)
    _set(wrench.body_2_wrench.force, -force)
    _set(wrench.body_2_wrench.torque, -torque)


def _set(vector: Any, values: FloatArray) -> None:
    vector.x, vector.y, vector.z = (float(value) for value in values)
