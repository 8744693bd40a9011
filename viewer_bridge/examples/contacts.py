"""Example `contacts`: a pydrake scene with both kinds of contact, publishing CONTACT_RESULTS over LCM.

`viewer-bridge example contacts` runs it in real time (the tests: `python -m
viewer_bridge.examples.contacts LCM_URL [SECONDS] [REALTIME]`, as fast as it can). A box (rigid hydroelastic
properties, so against the rigid half-space it falls back to point contact) and a sphere
(compliant hydroelastic: a contact surface with the half-space) fall onto a half-space in a
`hydroelastic_with_fallback` plant; `ConnectContactResultsToDrakeVisualizer` publishes them,
and a DrakeVisualizer the bodies (unsuffixed channels).
"""

from __future__ import annotations

import sys

from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    DrakeVisualizer,
    HalfSpace,
    ProximityProperties,
    Sphere,
)
from pydrake.lcm import DrakeLcm
from pydrake.math import RigidTransform
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    ConnectContactResultsToDrakeVisualizer,
    CoulombFriction,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder


def _properties(compliant: bool) -> ProximityProperties:
    properties = ProximityProperties()
    AddContactMaterial(dissipation=1.0, friction=CoulombFriction(0.8, 0.6), properties=properties)
    if compliant:
        AddCompliantHydroelasticProperties(
            resolution_hint=0.02, hydroelastic_modulus=2e5, properties=properties
        )
    else:
        AddRigidHydroelasticProperties(resolution_hint=0.05, properties=properties)
    return properties


def main(url: str, seconds: float = 0.5, realtime: float = 0.0) -> None:
    builder = DiagramBuilder()
    config = MultibodyPlantConfig(time_step=0.002, contact_model="hydroelastic_with_fallback")
    plant, scene_graph = AddMultibodyPlant(config, builder)
    ground = RigidTransform()
    plant.RegisterCollisionGeometry(plant.world_body(), ground, HalfSpace(), "ground", _properties(False))
    plant.RegisterVisualGeometry(plant.world_body(), ground, HalfSpace(), "ground", [0.5, 0.5, 0.5, 1.0])
    # Rigid box on rigid ground: no hydroelastic surface, so the fallback makes point contacts.
    box = plant.AddRigidBody("box", SpatialInertia.SolidBoxWithMass(1.0, 0.2, 0.2, 0.2))
    plant.RegisterCollisionGeometry(box, RigidTransform(), Box(0.2, 0.2, 0.2), "box", _properties(False))
    plant.RegisterVisualGeometry(box, RigidTransform(), Box(0.2, 0.2, 0.2), "box", [0.8, 0.3, 0.2, 1.0])
    sphere = plant.AddRigidBody("sphere", SpatialInertia.SolidSphereWithMass(1.0, 0.1))
    plant.RegisterCollisionGeometry(sphere, RigidTransform(), Sphere(0.1), "sphere", _properties(True))
    plant.RegisterVisualGeometry(sphere, RigidTransform(), Sphere(0.1), "sphere", [0.2, 0.3, 0.8, 1.0])
    plant.Finalize()
    lcm = DrakeLcm(url)
    ConnectContactResultsToDrakeVisualizer(builder, plant, scene_graph, lcm)
    DrakeVisualizer.AddToBuilder(builder, scene_graph, lcm)  # the bodies too, for snapshots
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant.SetFreeBodyPose(context, box, RigidTransform([0.0, 0.0, 0.12]))
    plant.SetFreeBodyPose(context, sphere, RigidTransform([0.5, 0.0, 0.11]))
    simulator.set_target_realtime_rate(realtime)
    simulator.AdvanceTo(seconds)


def run(url: str, seconds: float) -> None:
    """`viewer-bridge example contacts`: in real time."""
    main(url, seconds, 1.0)


if __name__ == "__main__":
    main(sys.argv[1], *(float(argument) for argument in sys.argv[2:]))
