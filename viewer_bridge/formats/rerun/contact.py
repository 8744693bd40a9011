"""Contact results as Rerun archetypes, in the world: one `Arrows3D` of forces (point contacts at
their points, hydroelastic ones at their centroids), one of hydroelastic moments, and each
hydroelastic surface a `Mesh3D` coloured per vertex by its pressure (`viewer_bridge.model.contact`'s
colour map and scales, as every other target draws them).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from viewer_bridge.model.contact import (
    FORCE_COLOR,
    MOMENT_COLOR,
    ContactDrawOptions,
    ContactResults,
    pressure_colors,
    pressure_range,
)


def contact_archetypes(results: ContactResults, options: ContactDrawOptions) -> dict[str, list[Any]]:
    """Archetypes by entity name under the contacts' entity: `forces`, `moments`, `surfaces/<i>`.

    Every entity is written each message (an empty arrow set when there is nothing), so a contact
    that ends disappears at that time; surfaces beyond the message's count are cleared.
    """
    hydro = results.hydroelastic
    starts = np.concatenate([results.point.points.reshape(-1, 3), *(c.centroid[None, :] for c in hydro)])
    forces = np.concatenate([results.point.forces.reshape(-1, 3), *(c.force[None, :] for c in hydro)])
    centroids = np.array([c.centroid for c in hydro]).reshape(-1, 3)
    moments = np.array([c.moment for c in hydro]).reshape(-1, 3)
    out: dict[str, list[Any]] = {
        "forces": [_arrows(starts, forces * options.force_scale, FORCE_COLOR, options)],
        "moments": [_arrows(centroids, moments * options.moment_scale, MOMENT_COLOR, options)],
    }
    if options.surfaces:
        low, high = pressure_range(results, options)
        for index, contact in enumerate(hydro):
            surface = contact.surface
            out[f"surfaces/{index}"] = [
                rr.Mesh3D(
                    vertex_positions=surface.vertices,
                    triangle_indices=surface.triangles,
                    vertex_colors=pressure_colors(surface.pressure, low, high),
                )
            ]
    return out


def _arrows(starts: Any, vectors: Any, color: tuple[float, ...], options: ContactDrawOptions) -> rr.Arrows3D:
    keep = np.linalg.norm(vectors, axis=1) >= max(options.min_length, 1e-12) if len(vectors) else []
    return rr.Arrows3D(
        origins=starts[keep].reshape(-1, 3),
        vectors=vectors[keep].reshape(-1, 3),
        radii=options.arrow_radius,
        colors=[color],
    )
