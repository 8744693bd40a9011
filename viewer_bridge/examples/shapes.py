"""Example `shapes`: a pydrake scene with every shape, published by DrakeVisualizer over LCM.

`viewer-bridge example shapes` runs it; the tests run it as
`python -m viewer_bridge.examples.shapes LCM_URL FOLDER [SECONDS]` (the mesh files written into
FOLDER). With SECONDS the simulation runs that long in real time (a live source); without, 0.1 s
as fast as it can. Two model instances of eight bodies fall onto a ground half-space. Each role
publishes on its own role-suffixed channels (the tests' illustration and proximity; the example
adds perception), so every way Drake lowers a shape is on the wire: a Mesh by file, Convex and
proximity meshes as mesh arrays, an in-memory mesh as JSON, a HalfSpace as a box.
"""

from __future__ import annotations

import sys
from pathlib import Path

from pydrake.common import MemoryFile
from pydrake.geometry import (
    Box,
    Capsule,
    Convex,
    Cylinder,
    DrakeVisualizer,
    DrakeVisualizerParams,
    Ellipsoid,
    HalfSpace,
    InMemoryMesh,
    Mesh,
    Role,
    Sphere,
)
from pydrake.lcm import DrakeLcm
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from viewer_bridge.examples.demo import DEMO_MESH, TETRAHEDRON_OBJ

TEST_ROLES = (Role.kIllustration, Role.kProximity)
EVERY_ROLE = (Role.kIllustration, Role.kProximity, Role.kPerception)


def main(url: str, folder: Path, seconds: float | None = None) -> None:
    lcm = DrakeLcm(url)
    simulator = build_simulator(lcm, folder)
    if seconds is None:
        simulator.AdvanceTo(0.1)  # free fall: poses change from frame to frame
    else:
        simulator.set_target_realtime_rate(1.0)
        simulator.AdvanceTo(seconds)


def run(url: str, seconds: float) -> None:
    """`viewer-bridge example shapes`: every role, in real time; the mesh file is the package's own,
    so a recording of it still finds the mesh later."""
    simulator = build_simulator(DrakeLcm(url), None, EVERY_ROLE)
    simulator.set_target_realtime_rate(1.0)
    simulator.AdvanceTo(seconds)


def build_simulator(lcm: DrakeLcm, folder: Path | None, roles: tuple[Role, ...] = TEST_ROLES) -> Simulator:
    """The scene with every shape, a DrakeVisualizer per role publishing on `lcm`; the mesh file
    is written into `folder` (None: the package's own copy)."""
    obj = DEMO_MESH if folder is None else folder / "tetrahedron.obj"
    if folder is not None:
        obj.write_text(TETRAHEDRON_OBJ)
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.001)
    shapes = [
        Box(0.1, 0.2, 0.3),
        Sphere(0.05),
        Cylinder(0.04, 0.3),
        Capsule(0.03, 0.2),
        Ellipsoid(0.1, 0.2, 0.3),
        Mesh(str(obj), 2.0),
        Convex(str(obj), 1.5),
        Mesh(InMemoryMesh(mesh_file=MemoryFile(TETRAHEDRON_OBJ, ".obj", "tetrahedron.obj")), 0.5),
    ]
    for model in range(2):  # two model instances, so robot_num differs between links
        instance = plant.AddModelInstance(f"robot{model}")
        for index, shape in enumerate(shapes):
            body = plant.AddRigidBody(f"body{index}", instance, SpatialInertia.SolidSphereWithMass(1.0, 0.1))
            pose = RigidTransform(RollPitchYaw(0.1 * index, 0.2, 0.3 + model), [index * 0.3, model, 0.5])
            color = [0.1 * index, 0.5, 0.2 * model, 1.0]
            plant.RegisterVisualGeometry(body, pose, shape, f"visual{index}", color)
            plant.RegisterCollisionGeometry(body, pose, shape, f"collision{index}", CoulombFriction(0.9, 0.5))
    ground = RigidTransform([0.0, 0.0, -0.1])
    plant.RegisterVisualGeometry(plant.world_body(), ground, HalfSpace(), "ground", [0.5, 0.5, 0.5, 1.0])
    plant.RegisterCollisionGeometry(
        plant.world_body(), ground, HalfSpace(), "ground", CoulombFriction(0.9, 0.5)
    )
    plant.Finalize()
    for role in roles:
        params = DrakeVisualizerParams(role=role, use_role_channel_suffix=True)
        DrakeVisualizer.AddToBuilder(builder, scene_graph, lcm, params)
    return Simulator(builder.Build())


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]), float(sys.argv[3]) if len(sys.argv) > 3 else None)
