"""Drake's scene to Rerun: the scene once per load (static), every link's frame each draw.

`drake_to_rerun` reads a role's loads and draws: a load becomes an entity per link and one per
geometry (`viewer_bridge.formats.rerun.scene`), logged static so a viewer that connects later
gets it; a draw becomes one chunk of `Transform3D` rows, world -> every link's frame, at the
draw's time on the `sim_time` timeline and its receive time on `receive_time`
(`viewer_bridge.formats.rerun.transforms`). Frames are named as on ROS's /tf, role prefixes
included, so the illustration and proximity streams never share a frame; entities are rooted
at the role (`proximity/plant/iiwa/iiwa_link_0`) under the route's destination (`/drake`).

Generic LCM channels (each numeric field as `Scalars` under `/lcm/<channel>/<field path>`) are
to come as a translator of their own beside this one, reading the generic LCM message type.
"""

from __future__ import annotations

from typing import Any

from viewer_bridge.formats.rerun.chunks import Stamp
from viewer_bridge.formats.rerun.scene import scene_batches
from viewer_bridge.formats.rerun.schema import encode_batches
from viewer_bridge.formats.rerun.transforms import TransformsEncoder
from viewer_bridge.translators.base import Output, Outputs
from viewer_bridge.translators.drake_stream import DrakeTranslator, role_of
from viewer_bridge.translators.options import FrameOptions
from viewer_bridge.translators.types import RERUN_CHUNKS_TYPE
from viewer_bridge.transports.base import Received

# The implicit frame of the root entity: the links' frames hang off the 3D view's own space.
ROOT_FRAME = "tf#/"


class RerunOptions(FrameOptions):
    world_frame: str = ROOT_FRAME  # the parent of every link frame (Drake's world link is this frame)


class DrakeToRerun(DrakeTranslator):
    """load -> static entities and archetypes; draw -> one chunk of link transforms."""

    Options = RerunOptions
    options: RerunOptions
    outputs = (Output("", RERUN_CHUNKS_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.encoder: TransformsEncoder | None = None

    def translate(self, message: Received) -> Outputs:
        scene, poses = self.drake.read(message)
        frames = self.options.frames(message.channel)
        root = (role_of(message.channel),)
        batches = [] if scene is None else scene_batches(scene, root, frames)
        if poses is not None:
            if self.encoder is None:  # one stream per translator: its role is its first channel's
                path = "/" + "/".join((*root, "transforms")).lstrip("/")
                self.encoder = TransformsEncoder(path, frames, frames.world_frame)
            batches.append(self.encoder.encode(poses, Stamp.of(poses.timestamp_ms * 1000, message.received_us)))
        return [(0, encode_batches(batches))] if batches else []
