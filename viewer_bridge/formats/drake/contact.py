"""Drake's `lcmt_contact_results_for_viz` (channel `CONTACT_RESULTS`) read as `ContactResults`.

The generic codec (`viewer_bridge.lcmcodec`) checks the bytes: counts against the buffer, strings, and
non-finite doubles, each a `DecodeError` naming the field and offset. Here the rest is checked:
a surface's polygon stream (counts of at least 3, indices within the vertices, the stream used
up exactly). Polygons are fanned into triangles; Drake sends triangles already, which take a
vectorised path. (Writing the message back, for tests and benchmarks:
tests/formats/drake/oracle.py.)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from viewer_bridge.errors import DecodeError
from viewer_bridge.lcmcodec.codecs import CONTACT_RESULTS
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.lcmcodec.serde import LcmMessage
from viewer_bridge.model.contact import (
    ContactBody,
    ContactResults,
    ContactSurface,
    HydroelasticContact,
    PointContacts,
)
from viewer_bridge.model.scene import FloatArray, IntArray

_TYPE = CONTACT_RESULTS.type_name


def decode_contact_results(data: Buffer) -> ContactResults:
    """`CONTACT_RESULTS` bytes as `ContactResults`; `DecodeError` for anything malformed."""
    return contact_results_from_lcm(CONTACT_RESULTS.strict.decode(data))


def contact_results_from_lcm(message: LcmMessage) -> ContactResults:
    pairs = message.point_pair_contact_info
    point = PointContacts(
        tuple((pair.body1_name, pair.body2_name) for pair in pairs),
        _rows([pair.contact_point for pair in pairs]),
        _rows([pair.contact_force for pair in pairs]),
        _rows([pair.normal for pair in pairs]),
    )
    hydroelastic = tuple(
        _hydroelastic(surface, index) for index, surface in enumerate(message.hydroelastic_contacts)
    )
    return ContactResults(int(message.timestamp), point, hydroelastic)


def _rows(values: Sequence[Sequence[float]]) -> FloatArray:
    return np.array(values, dtype=np.float64).reshape(-1, 3)


def _hydroelastic(message: LcmMessage, index: int) -> HydroelasticContact:
    body1 = ContactBody(
        message.body1_name,
        message.model1_name,
        message.geometry1_name,
        message.body1_unique,
        message.collision_count1,
    )
    body2 = ContactBody(
        message.body2_name,
        message.model2_name,
        message.geometry2_name,
        message.body2_unique,
        message.collision_count2,
    )
    vertices = np.array([(p.x, p.y, p.z) for p in message.p_WV], dtype=np.float64).reshape(-1, 3)
    field = f"hydroelastic_contacts[{index}].poly_data"
    triangles = triangles_from_polygons(np.asarray(message.poly_data, dtype=np.int64), len(vertices), field)
    surface = ContactSurface(vertices, np.asarray(message.pressure, dtype=np.float64), triangles)
    return HydroelasticContact(
        body1,
        body2,
        np.array(message.centroid_W, dtype=np.float64),
        np.array(message.force_C_W, dtype=np.float64),
        np.array(message.moment_C_W, dtype=np.float64),
        surface,
    )


def triangles_from_polygons(poly_data: IntArray, vertex_count: int, field: str) -> IntArray:
    """Drake's polygon stream (count, indices..., count, indices...) as T x 3 triangles (fans).

    Raises `DecodeError` at the element that is wrong: a count below 3 or past the stream's
    end, or an index outside the vertices.
    """
    size = len(poly_data)
    if size % 4 == 0 and size and (poly_data[::4] == 3).all():  # all triangles: Drake's case
        triangles = poly_data.reshape(-1, 4)[:, 1:]
        offsets = 4 * np.arange(size // 4)[:, None] + np.arange(1, 4)
    else:
        triangles, offsets = _fan(poly_data.tolist(), field)
    bad = (triangles < 0) | (triangles >= vertex_count)
    if bad.any():
        offset = int(offsets[bad][0])
        reason = f"vertex index {int(poly_data[offset])} is outside the {vertex_count} vertices"
        raise DecodeError(_TYPE, field, offset, reason, unit="element")
    result: IntArray = np.ascontiguousarray(triangles, dtype=np.int64)
    return result


def _fan(values: list[int], field: str) -> tuple[IntArray, IntArray]:
    """Any polygons as triangle fans, with each corner's offset in the stream (for errors)."""
    offsets: list[tuple[int, int, int]] = []
    offset = 0
    while offset < len(values):
        count = values[offset]
        if count < 3:
            raise DecodeError(_TYPE, field, offset, f"polygon of {count} vertices", unit="element")
        if offset + 1 + count > len(values):
            reason = f"polygon of {count} vertices runs past the end ({len(values)} values)"
            raise DecodeError(_TYPE, field, offset, reason, unit="element")
        first = offset + 1
        offsets += [(first, first + k, first + k + 1) for k in range(1, count - 1)]
        offset += 1 + count
    corner_offsets = np.array(offsets, dtype=np.int64).reshape(-1, 3)
    triangles: IntArray = np.asarray(values, dtype=np.int64)[corner_offsets] if offsets else corner_offsets
    return triangles, corner_offsets
