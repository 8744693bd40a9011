"""Drake's messages built field by field from the neutral models: the slow, readable writers only
tests and benchmarks call. `draw_from_poses` is the reference `DrawEncoder`'s bytes are held to;
`contact_results_to_lcm` writes contact results back (triangles as 3-vertex polygons) for tests and
bench/contacts.py to decode.
"""

from __future__ import annotations

import numpy as np

from viewer_bridge.lcmcodec.codecs import CODECS, CONTACT_RESULTS, DRAW
from viewer_bridge.lcmcodec.serde import LcmMessage
from viewer_bridge.model.contact import ContactResults, HydroelasticContact
from viewer_bridge.model.scene import LinkPoses

POINT_PAIR = CODECS["drake.lcmt_point_pair_contact_info_for_viz"]
SURFACE = CODECS["drake.lcmt_hydroelastic_contact_surface_for_viz"]
POINT = CODECS["drake.lcmt_point"]


def draw_from_poses(poses: LinkPoses) -> LcmMessage:
    """The `lcmt_viewer_draw` message of a frame (float32 on the wire, as Drake sends it)."""
    return DRAW.message_class(
        timestamp=int(poses.timestamp_ms),
        num_links=len(poses),
        link_name=list(poses.names),
        robot_num=[int(value) for value in poses.robot_nums],
        position=np.asarray(poses.positions, dtype=np.float64).tolist(),
        quaternion=np.asarray(poses.quaternions_wxyz, dtype=np.float64).tolist(),
    )


def contact_results_to_lcm(results: ContactResults) -> LcmMessage:
    """`ContactResults` as `lcmt_contact_results_for_viz` (triangles as 3-vertex polygons)."""
    pairs = [
        POINT_PAIR.message_class(
            timestamp=results.timestamp_us,
            body1_name=body1,
            body2_name=body2,
            contact_point=point,
            contact_force=force,
            normal=normal,
        )
        for (body1, body2), point, force, normal in zip(
            results.point.body_pairs,
            results.point.points.tolist(),
            results.point.forces.tolist(),
            results.point.normals.tolist(),
            strict=True,
        )
    ]
    surfaces = [_surface_message(contact) for contact in results.hydroelastic]
    return CONTACT_RESULTS.message_class(
        timestamp=results.timestamp_us,
        num_point_pair_contacts=len(pairs),
        point_pair_contact_info=pairs,
        num_hydroelastic_contacts=len(surfaces),
        hydroelastic_contacts=surfaces,
    )


def _surface_message(contact: HydroelasticContact) -> LcmMessage:
    surface = contact.surface
    triangles = surface.triangles
    poly = np.concatenate((np.full((len(triangles), 1), 3), triangles), axis=1).reshape(-1).tolist()
    one, two = contact.body1, contact.body2
    return SURFACE.message_class(
        geometry1_name=one.geometry,
        body1_name=one.body,
        model1_name=one.model,
        body1_unique=one.body_unique,
        collision_count1=one.collision_count,
        geometry2_name=two.geometry,
        body2_name=two.body,
        model2_name=two.model,
        body2_unique=two.body_unique,
        collision_count2=two.collision_count,
        centroid_W=contact.centroid.tolist(),
        force_C_W=contact.force.tolist(),
        moment_C_W=contact.moment.tolist(),
        num_quadrature_points=0,
        quadrature_point_data=[],
        num_vertices=len(surface.vertices),
        p_WV=[POINT.message_class(x=x, y=y, z=z) for x, y, z in surface.vertices.tolist()],
        pressure=surface.pressure.tolist(),
        poly_data_int_count=len(poly),
        poly_data=poly,
    )
