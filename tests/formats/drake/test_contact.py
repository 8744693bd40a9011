"""Drake's `lcmt_contact_results_for_viz` (viewer_bridge/formats/drake/contact.py), checked against pydrake's
own class: values, polygons fanned into triangles, and bad input as `DecodeError`s."""

from __future__ import annotations

from typing import Any

import pytest

from tests.formats.drake.oracle import contact_results_to_lcm
from tests.optional import peer
from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.contact import decode_contact_results

# Drake's own lcm-gen classes, shipped with pydrake: imported by the tests that use them
drake_lcmtypes = peer("drake")


def pydrake_results(polygons: list[int] | None = None, force_z: float = 9.81) -> Any:
    """A message built with pydrake's classes: two point contacts and one surface (a quad and a triangle)."""
    message = drake_lcmtypes.lcmt_contact_results_for_viz()
    message.timestamp = 1_234_567
    for index in range(2):
        pair = drake_lcmtypes.lcmt_point_pair_contact_info_for_viz()
        pair.timestamp = message.timestamp
        pair.body1_name, pair.body2_name = "world(0)", f"box{index}(1)"
        pair.contact_point = [0.1 * index, 0.2, -1e-5]
        pair.contact_force = [0.5, -0.25, force_z]
        pair.normal = [0.0, 0.0, 1.0]
        message.point_pair_contact_info.append(pair)
    message.num_point_pair_contacts = 2
    surface = drake_lcmtypes.lcmt_hydroelastic_contact_surface_for_viz()
    surface.geometry1_name, surface.body1_name, surface.model1_name = "ground", "world", "WorldModelInstance"
    surface.geometry2_name, surface.body2_name, surface.model2_name = (
        "sphere",
        "sphere",
        "DefaultModelInstance",
    )
    surface.body1_unique = surface.body2_unique = True
    surface.collision_count1 = surface.collision_count2 = 1
    surface.centroid_W, surface.force_C_W, surface.moment_C_W = [0.5, 0, 0], [0, 0, -9.4], [0.01, 0.02, 0]
    for x, y in [(0, 0), (1, 0), (1, 1), (0, 1), (2, 0.5)]:
        point = drake_lcmtypes.lcmt_point()
        point.x, point.y, point.z = x * 0.01, y * 0.01, 0.0
        surface.p_WV.append(point)
    surface.num_vertices = 5
    surface.pressure = [0.0, 1e5, 2e5, 3e5, 4e5]
    surface.poly_data = polygons if polygons is not None else [4, 0, 1, 2, 3, 3, 1, 4, 2]
    surface.poly_data_int_count = len(surface.poly_data)
    message.hydroelastic_contacts.append(surface)
    message.num_hydroelastic_contacts = 1
    return message


def test_decoded_values_equal_pydrake_and_encode_back() -> None:
    message = pydrake_results(polygons=[3, 0, 1, 2, 3, 0, 2, 3])  # triangles: re-encoded byte for byte
    results = decode_contact_results(message.encode())
    assert results.timestamp_us == 1_234_567
    assert results.point.body_pairs == (("world(0)", "box0(1)"), ("world(0)", "box1(1)"))
    assert results.point.points.tolist() == [list(p.contact_point) for p in message.point_pair_contact_info]
    assert results.point.forces.tolist() == [list(p.contact_force) for p in message.point_pair_contact_info]
    (contact,) = results.hydroelastic
    assert (contact.body1.geometry, contact.body2.body, contact.body2.model) == (
        "ground",
        "sphere",
        "DefaultModelInstance",
    )
    assert contact.surface.vertices.tolist() == [
        [p.x, p.y, p.z] for p in message.hydroelastic_contacts[0].p_WV
    ]
    assert contact.surface.triangles.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert contact_results_to_lcm(results).encode() == message.encode()


def test_polygons_are_fanned_into_triangles() -> None:
    (contact,) = decode_contact_results(pydrake_results().encode()).hydroelastic
    assert contact.surface.triangles.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 2]]


@pytest.mark.parametrize(
    ("polygons", "error"),
    [
        ([3, 0, 1, 7], "poly_data at element 3: vertex index 7 is outside the 5 vertices"),
        ([3, 0, 1, -1], "poly_data at element 3: vertex index -1 is outside"),
        ([2, 0, 1], "poly_data at element 0: polygon of 2 vertices"),
        ([3, 0, 1, 2, 4, 0, 1], "poly_data at element 4: polygon of 4 vertices runs past the end"),
        ([3, 0, 1, 2, 2**31 - 1], "polygon of 2147483647 vertices runs past the end"),
    ],
)
def test_bad_polygons_are_decode_errors(polygons: list[int], error: str) -> None:
    with pytest.raises(DecodeError, match=error) as caught:
        decode_contact_results(pydrake_results(polygons).encode())
    assert caught.value.field.startswith("hydroelastic_contacts[0].")


def test_nan_and_huge_counts_are_decode_errors() -> None:
    with pytest.raises(DecodeError, match=r"point_pair_contact_info\[0\].contact_force\[2\].*non-finite"):
        decode_contact_results(pydrake_results(force_z=float("nan")).encode())
    data = bytearray(pydrake_results().encode())
    data[16:20] = (2**31 - 1).to_bytes(4, "big")  # num_point_pair_contacts
    with pytest.raises(
        DecodeError, match="num_point_pair_contacts|point_pair_contact_info.*count 2147483647"
    ):
        decode_contact_results(bytes(data))
