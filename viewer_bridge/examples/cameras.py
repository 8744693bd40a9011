"""Example `cameras`: a pydrake scene watched by simulated cameras (ApplyCameraConfig) over LCM.

`viewer-bridge example cameras` runs it (the tests: `python -m viewer_bridge.examples.cameras
LCM_URL SECONDS`). The simulation runs that long in real time.
Two cameras look at a few shapes on a ground plane, both with colour, depth and label images
rendered by RenderEngineVtk (headless, EGL): `left` publishes zlib-compressed (Drake's default),
`right` uncompressed, each on DRAKE_RGBD_CAMERA_IMAGES_<name>. Nothing moves, so every image a
camera sends is the same picture.
"""

from __future__ import annotations

import sys

from pydrake.common.schema import Transform
from pydrake.geometry import Box, Capsule, Cylinder, HalfSpace, Sphere
from pydrake.lcm import DrakeLcm
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import ApplyCameraConfig, CameraConfig

# name -> (width, height, do_compress); one size, so that one camera_info option fits both.
CAMERAS = {"left": (160, 120, True), "right": (160, 120, False)}
FOV_Y_DEGREES = 45.0  # CameraConfig's default
FPS = 10.0


def build_simulator(
    lcm: DrakeLcm, cameras: dict[str, tuple[int, int, bool]] = CAMERAS, label: bool = True
) -> Simulator:
    """The scene and its cameras (name -> width, height, do_compress), publishing on `lcm`."""
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, 0.0)
    shapes = [Box(0.2, 0.2, 0.2), Sphere(0.1), Cylinder(0.08, 0.25), Capsule(0.06, 0.2)]
    for index, shape in enumerate(shapes):  # a body each, welded: the label image tells them apart
        body = plant.AddRigidBody(f"body{index}", SpatialInertia.SolidSphereWithMass(1.0, 0.1))
        pose = RigidTransform(RollPitchYaw(0.0, 0.0, 0.4 * index), [0.3 * index - 0.45, 0.0, 0.12])
        plant.WeldFrames(plant.world_frame(), body.body_frame(), pose)
        plant.RegisterVisualGeometry(body, RigidTransform(), shape, f"shape{index}",
                                     [0.9 - 0.2 * index, 0.3 + 0.15 * index, 0.2 + 0.2 * index, 1.0])  # fmt: skip
    plant.RegisterVisualGeometry(
        plant.world_body(), RigidTransform(), HalfSpace(), "ground", [0.5, 0.5, 0.5, 1.0]
    )
    plant.Finalize()
    for offset, (name, (width, height, compress)) in enumerate(cameras.items()):
        config = CameraConfig(name=name, width=width, height=height, rgb=True, depth=True, label=label,
                              do_compress=compress, renderer_class="RenderEngineVtk", fps=FPS)  # fmt: skip
        config.focal = CameraConfig.FovDegrees(y=FOV_Y_DEGREES)
        # Looking down at the shapes from the front, the right camera a little to the side.
        config.X_PB = Transform(RigidTransform(RollPitchYaw(-2.2, 0.0, 0.0), [0.3 * offset, -1.2, 0.9]))
        ApplyCameraConfig(config=config, builder=builder, lcm=lcm)
    return Simulator(builder.Build())


def main(url: str, seconds: float) -> None:
    simulator = build_simulator(DrakeLcm(url))
    simulator.set_target_realtime_rate(1.0)
    simulator.AdvanceTo(seconds)


run = main  # `viewer-bridge example cameras`


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
