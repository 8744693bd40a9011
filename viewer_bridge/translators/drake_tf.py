"""Drake's scene the way ROS consumes motion: a TF tree per draw, markers fixed in link frames.

`drake_to_tf` publishes each draw as one `tf2_msgs/TFMessage` on `/tf` (world -> every link)
and, once per load, the links the load has but draws never move on `/tf_static` (latched, as
tf2 expects). `drake_to_link_markers` publishes the scene's markers once per load, each in its
link's frame and `frame_locked`, so a draw costs RViz one TFMessage, not a re-posed MarkerArray.

Roles: Drake's illustration scene (unsuffixed or `_ILLUSTRATION` channels) names its frames
`plant/iiwa/iiwa_link_0`; the proximity and perception scenes prefix theirs (`proximity/...`,
`perception/...`), so the three trees never collide on one `/tf`. `frame_prefix` overrides.

Stamps: the bridge's clock (the config's `time:`): the receive time by default, which RViz and
tf2 accept out of the box; with `time: sim`, Drake's sim time, for nodes with `use_sim_time` (the
config then publishes `/clock` too). A route's `stamp:` option overrides the clock for that route.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from viewer_bridge.formats.ros.cdr import time_parts, time_parts_from_us
from viewer_bridge.formats.ros.markers import marker_array_in_link_frames_cdr
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY, TF_MESSAGE, WORLD
from viewer_bridge.formats.ros.tf import TransformsEncoder
from viewer_bridge.model.scene import LinkPoses, Scene
from viewer_bridge.translators.base import Output, Outputs
from viewer_bridge.translators.drake_stream import DrakeTranslator, PerLoadTranslator
from viewer_bridge.translators.options import FrameOptions, MarkerOptions, StampOptions
from viewer_bridge.translators.types import ros_type
from viewer_bridge.transports.base import Received


class TfOptions(FrameOptions, StampOptions):
    """How frames are named, and the clock of the stamps."""


class DrakeToTf(DrakeTranslator):
    """draw -> `TFMessage` on the destination (`/tf`); per load, the links draws never move -> `<it>_static`."""

    Options = TfOptions
    options: TfOptions
    outputs = (
        Output("", ros_type(TF_MESSAGE)),
        Output("_static", ros_type(TF_MESSAGE), latched=True),
    )

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.encoder: TransformsEncoder | None = None
        self._static_due = False

    def translate(self, message: Received) -> Outputs:
        scene, poses = self.drake.read(message)
        if scene is not None:
            self._static_due = True
        if poses is None:
            return []
        if self.encoder is None:  # one stream per translator: its role is its first channel's
            self.encoder = TransformsEncoder(self.options.frames(message.channel))
        stamp = self._stamp(message, poses)
        out: Outputs = []
        if self._static_due and self.drake.scene is not None:
            self._static_due = False
            fixed = _never_drawn(self.drake.scene, poses)
            if len(fixed):
                out.append((1, TransformsEncoder(self.encoder.frames).encode(fixed, stamp)))
        out.append((0, self.encoder.encode(poses, stamp)))
        return out

    def _stamp(self, message: Received, poses: LinkPoses) -> tuple[int, int]:
        """(sec, nanosec); `EncodeError` for a time whose seconds do not fit an int32."""
        if self.options.sim_stamps(self.shared.clock):
            return time_parts(poses.timestamp_ms)
        return time_parts_from_us(message.received_us)


def _never_drawn(scene: Scene, poses: LinkPoses) -> LinkPoses:
    """The links a load names that the draw does not pose (the world link aside), at the identity:
    Drake poses their geometry in the world frame already."""
    drawn = set(poses.names)
    names = tuple(link.name for link in scene.links if link.name != WORLD and link.name not in drawn)
    count = len(names)
    wxyz = np.zeros((count, 4))
    wxyz[:, 0] = 1.0
    return LinkPoses(poses.timestamp_ms, names, np.zeros(count, np.int32), np.zeros((count, 3)), wxyz)


class LinkMarkerOptions(MarkerOptions, FrameOptions):
    """The marker table's options, and how link frames are named (as `drake_to_tf` names them)."""


class DrakeToLinkMarkers(PerLoadTranslator):
    """load -> `MarkerArray`, every marker in its link's TF frame, `frame_locked`; once per load,
    latched. Draws publish nothing (TF moves the frames); a draw for a scene this route has not
    published brings that scene's array."""

    Options = LinkMarkerOptions
    options: LinkMarkerOptions
    outputs = (Output("", ros_type(MARKER_ARRAY), latched=True),)

    def on_scene(self, scene: Scene, channel: str) -> Outputs:
        frames = self.options.frames(channel)
        return [(0, marker_array_in_link_frames_cdr(scene, frames, self.options.table_overrides()))]
