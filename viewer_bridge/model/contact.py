"""Contact results as neutral types, and how they are drawn: arrows and pressure-coloured surfaces.

Drake publishes `lcmt_contact_results_for_viz` on `CONTACT_RESULTS`; `viewer_bridge.formats.drake.contact`
reads it into `ContactResults`. Every target draws contacts through one mechanism:
`contact_scene` lowers them to ordinary scene shapes (a `Line` with an end head per force and
moment, a `TriangleMesh` with per-vertex colours per hydroelastic surface), which each format's
shape table in `mappings/` already knows how to write. Only the wrenches (ROS 2 WrenchStamped,
ign Contacts) are written from these types directly.

Sign conventions are Drake's: a point contact's force acts on body 2 (body B) at the contact
point; a hydroelastic contact's force and moment act on body 1 at the surface's centroid. All
vectors are in the world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from viewer_bridge.model.scene import FloatArray, Geometry, IntArray, Line, Link, Rgba, Scene, TriangleMesh


@dataclass(frozen=True, eq=False, slots=True)
class PointContacts:
    """N point contacts as arrays: body names (N pairs), points, forces on body 2, normals (N x 3)."""

    body_pairs: tuple[tuple[str, str], ...]
    points: FloatArray
    forces: FloatArray
    normals: FloatArray

    def __len__(self) -> int:
        return len(self.body_pairs)


@dataclass(frozen=True, slots=True)
class ContactBody:
    """One side of a hydroelastic contact: the body, its model instance and the geometry."""

    body: str
    model: str = ""
    geometry: str = ""
    body_unique: bool = True  # the body name alone names it; otherwise qualify it by model
    collision_count: int = 1


@dataclass(frozen=True, eq=False, slots=True)
class ContactSurface:
    """A hydroelastic contact surface: vertices (V x 3), pressure per vertex (V, Pa), triangles
    (T x 3; Drake's polygons are fanned into triangles)."""

    vertices: FloatArray
    pressure: FloatArray
    triangles: IntArray


@dataclass(frozen=True, eq=False, slots=True)
class HydroelasticContact:
    """The resultant force and moment on body 1 at the surface's centroid, and the surface."""

    body1: ContactBody
    body2: ContactBody
    centroid: FloatArray  # 3
    force: FloatArray  # 3, on body 1
    moment: FloatArray  # 3, on body 1 about the centroid
    surface: ContactSurface


@dataclass(frozen=True, eq=False, slots=True)
class ContactResults:
    """Every contact at one instant; `timestamp_us` is Drake's sim time in microseconds."""

    timestamp_us: int
    point: PointContacts
    hydroelastic: tuple[HydroelasticContact, ...] = ()

    def pair_count(self) -> int:
        return len(self.point) + len(self.hydroelastic)


# --- drawing: contacts lowered to scene shapes -----------------------------------------------------

# The pressure colour map: a linear ramp through these stops from the low to the high end of the
# range (blue, cyan, green, yellow, red: the "jet" ramp meldis users know from contact plots).
PRESSURE_STOPS = np.array(
    [[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 0.0]], dtype=np.float64
)
FORCE_COLOR: Rgba = (1.0, 0.1, 0.1, 1.0)  # point and hydroelastic forces
MOMENT_COLOR: Rgba = (0.1, 0.3, 1.0, 1.0)
SURFACE_LINK = "contact::surfaces"  # names the scene links, hence ROS namespaces and tree paths
FORCE_LINK = "contact::forces"
MOMENT_LINK = "contact::moments"


class ContactDrawOptions(BaseModel):
    """How contacts are drawn (every contact translator that draws takes these)."""

    model_config = ConfigDict(extra="forbid", frozen=True)  # as a translator's options: checked at load

    force_scale: float = Field(0.01, gt=0)  # arrow length in metres per newton
    moment_scale: float = Field(0.1, gt=0)  # arrow length in metres per newton-metre
    arrow_radius: float = Field(0.005, gt=0)  # shaft radius; heads are 2.5x as wide, 5x as long
    min_length: float = Field(1e-4, ge=0)  # arrows shorter than this (metres) are not drawn
    pressure_range: tuple[float, float] | None = None  # Pa; None: 0 to the message's highest pressure
    surfaces: bool = True  # draw hydroelastic surfaces


def pressure_colors(pressure: FloatArray, low: float, high: float) -> FloatArray:
    """V x 3 RGB in [0, 1] for pressures, by `PRESSURE_STOPS` over [low, high] (clipped)."""
    span = high - low
    t = np.clip((pressure - low) / span, 0.0, 1.0) if span > 0 else np.zeros_like(pressure)
    position = t * (len(PRESSURE_STOPS) - 1)
    below = np.minimum(position.astype(np.int64), len(PRESSURE_STOPS) - 2)
    weight = (position - below)[:, None]
    colors: FloatArray = PRESSURE_STOPS[below] * (1.0 - weight) + PRESSURE_STOPS[below + 1] * weight
    return colors


def pressure_range(results: ContactResults, options: ContactDrawOptions) -> tuple[float, float]:
    """The range the colour map spans: the option, else 0 to the highest pressure sent."""
    if options.pressure_range is not None:
        return options.pressure_range
    highest = max((float(c.surface.pressure.max(initial=0.0)) for c in results.hydroelastic), default=0.0)
    return 0.0, highest


def contact_scene(results: ContactResults, options: ContactDrawOptions | None = None) -> Scene:
    """The contacts as a scene in the world frame: links `contact::forces` (an arrow per force),
    `contact::moments` (per hydroelastic moment) and `contact::surfaces` (pressure-coloured meshes)."""
    options = options or ContactDrawOptions()
    forces: list[Geometry] = []
    moments: list[Geometry] = []
    starts = [results.point.points] + [c.centroid[None, :] for c in results.hydroelastic]
    force_vectors = [results.point.forces] + [c.force[None, :] for c in results.hydroelastic]
    if results.pair_count():
        forces = _arrows(
            np.concatenate(starts), np.concatenate(force_vectors) * options.force_scale, FORCE_COLOR, options
        )
    if results.hydroelastic:
        centroids = np.array([c.centroid for c in results.hydroelastic])
        moment_vectors = np.array([c.moment for c in results.hydroelastic]) * options.moment_scale
        moments = _arrows(centroids, moment_vectors, MOMENT_COLOR, options)
    links = [Link(FORCE_LINK, 0, tuple(forces)), Link(MOMENT_LINK, 0, tuple(moments))]
    if options.surfaces:
        low, high = pressure_range(results, options)
        surfaces = tuple(
            _surface(c.surface, low, high) for c in results.hydroelastic if len(c.surface.triangles)
        )
        links.append(Link(SURFACE_LINK, 0, surfaces))
    return Scene(tuple(links))


def _surface(surface: ContactSurface, low: float, high: float) -> Geometry:
    """A surface coloured per vertex; its one colour (for targets without vertex colours) is the
    colour of its mean pressure."""
    mean = pressure_colors(np.array([surface.pressure.mean()]), low, high)[0]
    mesh = TriangleMesh(surface.vertices, surface.triangles, pressure_colors(surface.pressure, low, high))
    return Geometry(mesh, color=(float(mean[0]), float(mean[1]), float(mean[2]), 1.0))


def _arrows(
    starts: FloatArray, vectors: FloatArray, color: Rgba, options: ContactDrawOptions
) -> list[Geometry]:
    """An arrow (a two-point `Line` with an end head) per row; too short ones are left out."""
    radius = options.arrow_radius
    keep = np.linalg.norm(vectors, axis=1) >= max(options.min_length, 1e-12)
    ends = starts + vectors
    return [
        Geometry(
            Line(
                np.array([start, end]),
                radius=radius,
                end_head=True,
                head_radius=2.5 * radius,
                head_length=5 * radius,
            ),
            color=color,
        )
        for start, end in zip(starts[keep], ends[keep], strict=True)
    ]
