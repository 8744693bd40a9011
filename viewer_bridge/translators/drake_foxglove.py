"""Drake's scene to Foxglove: the scene once per load, the frames every draw.

`drake_to_scene_update`: load -> `foxglove.SceneUpdate`, an entity per link in its link's frame
(latched: a client that connects later still gets the scene). `drake_to_frame_transforms`: draw
-> `foxglove.FrameTransforms`, world -> every link, stamped by the bridge's clock (the config's
`time:`: receive time, or Drake's sim time with `time: sim`) as `/tf` is; a draw costs
one transform list, never a re-sent scene. Frames are named as on ROS's /tf, role prefixes
included (see `drake_tf`), so one naming serves RViz and Foxglove alike.
"""

from __future__ import annotations

from typing import Any

from viewer_bridge.formats.foxglove.scene import scene_update
from viewer_bridge.formats.foxglove.transforms import FrameTransformsEncoder
from viewer_bridge.model.scene import Scene
from viewer_bridge.model.sim_time import sec_nsec_from_ms, sec_nsec_from_us
from viewer_bridge.translators.base import Output, Outputs
from viewer_bridge.translators.drake_stream import DrawReader, PerLoadTranslator
from viewer_bridge.translators.options import FrameOptions, StampOptions
from viewer_bridge.translators.types import DRAW_TYPE, FRAME_TRANSFORMS_TYPE, SCENE_UPDATE_TYPE
from viewer_bridge.transports.base import Received


class DrakeToSceneUpdate(PerLoadTranslator):
    """load -> `foxglove.SceneUpdate` (latched); a draw for a scene not yet sent brings it."""

    Options = FrameOptions
    options: FrameOptions
    outputs = (Output("", SCENE_UPDATE_TYPE, latched=True),)

    def on_scene(self, scene: Scene, channel: str) -> Outputs:
        return [(0, scene_update(scene, self.options.frames(channel)).SerializeToString())]


class FrameTransformsOptions(FrameOptions, StampOptions):
    """How frames are named, and the clock of the stamps."""


class DrakeToFrameTransforms(DrawReader):
    """draw -> `foxglove.FrameTransforms`: world -> every link, from the draw arrays."""

    Options = FrameTransformsOptions
    options: FrameTransformsOptions
    reads = (DRAW_TYPE,)
    outputs = (Output("", FRAME_TRANSFORMS_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.encoder: FrameTransformsEncoder | None = None

    def translate(self, message: Received) -> Outputs:
        poses = self.draw_poses(message)
        if self.encoder is None:  # one stream per translator: its role is its first channel's
            self.encoder = FrameTransformsEncoder(self.options.frames(message.channel))
        if self.options.sim_stamps(self.shared.clock):
            stamp = sec_nsec_from_ms(poses.timestamp_ms)
        else:
            stamp = sec_nsec_from_us(message.received_us)
        return [(0, self.encoder.encode(poses, stamp))]
