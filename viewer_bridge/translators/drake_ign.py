"""Drake's LCM scene to ign/gz-transport (ign-msgs 8 / gz-msgs protobuf), and Pose_V back.

Each translator names its messages once, by their short names (`Pose_V`): the ign transport
spells them in its package, unless a route's `package` option picks one (`IgnOptions`).
"""

from __future__ import annotations

import time
from typing import Any, ClassVar

from pydantic import Field

from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.ign.model import model_bytes, model_v_bytes
from viewer_bridge.formats.ign.poses import PosesEncoder, poses_from_pose_v
from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.model.scene import Scene
from viewer_bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from viewer_bridge.translators.drake_stream import DrakeTranslator, DrawReader
from viewer_bridge.translators.options import IgnOptions
from viewer_bridge.translators.types import DRAW_TYPE, LOAD_TYPE, ign_type
from viewer_bridge.transports.base import MessageType, Received


class _DrakeToIgn(Translator):
    """Base of Drake -> ign-transport: one output, the message `message_name`."""

    Options: ClassVar[type[TranslatorOptions]] = IgnOptions
    options: IgnOptions
    message_name: ClassVar[str]
    reads: tuple[MessageType, ...] = (DRAW_TYPE,)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        # What the class declares (checked against the route's transports when the config loads);
        # an instance names the package its options pick, if they pick one.
        super().__init_subclass__(**kwargs)
        cls.outputs = (Output("", ign_type(cls.message_name), latched=True),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.outputs = (Output("", self.options.message_type(self.message_name), latched=True),)


class ModelOptions(IgnOptions):
    republish_s: float = Field(1.0, ge=0)  # ign-transport has no latching: re-send for late subscribers


class DrakeToIgnModel(_DrakeToIgn, DrakeTranslator):
    """load -> `Model` (every link of the scene). ign-transport has no latching, so the model is
    published again every `republish_s` seconds while draws flow, for subscribers that start
    late; its link poses follow the latest draw."""

    Options = ModelOptions
    options: ModelOptions
    message_name = "Model"
    reads = (LOAD_TYPE, DRAW_TYPE)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._published_at = float("-inf")

    def build(self, scene: Scene) -> bytes:
        return model_bytes(scene)

    def translate(self, message: Received) -> Outputs:
        scene, poses = self.drake.read(message)
        now = time.monotonic()
        if scene is not None:
            self._published_at = now
            return [(0, self.build(scene))]
        if poses is None or self.drake.scene is None or now - self._published_at < self.options.republish_s:
            return []
        self._published_at = now
        return [(0, self.build(self.drake.scene.with_poses(poses)))]


class DrakeToIgnModelV(DrakeToIgnModel):
    """load -> `Model_V`: a Model per robot_num (model instance); republished like the Model."""

    message_name = "Model_V"

    def build(self, scene: Scene) -> bytes:
        return model_v_bytes(scene)


class DrakeToIgnPoseV(_DrakeToIgn, DrawReader):
    """draw -> `Pose_V`: a Pose per link, named with the link's Drake name.

    Written by `PosesEncoder` (the bytes protobuf writes for the same message, without objects).
    """

    message_name = "Pose_V"

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.encoder = PosesEncoder(self.message_name)

    def translate(self, message: Received) -> Outputs:
        return [(0, self.encoder.encode(self.draw_poses(message)))]


class DrakeToIgnPosesStamped(DrakeToIgnPoseV):
    """draw -> the legacy `PosesStamped` (sim time in `time` too), for older tools."""

    message_name = "PosesStamped"


class PoseVToDrawOptions(IgnOptions):
    robot_nums: dict[str, int] | None = None  # link name -> model instance; others get 0


class IgnPoseVToDrakeDraw(Translator):
    """ign `Pose_V` -> `lcmt_viewer_draw` (names from `Pose.name`, robot_nums from the options)."""

    Options = PoseVToDrawOptions
    options: PoseVToDrawOptions
    reads = (ign_type("Pose_V"),)  # in either package: the ign transport takes both spellings
    outputs = (Output("", DRAW_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.reads = (self.options.message_type("Pose_V"),)
        self.encoder = DrawEncoder()

    def translate(self, message: Received) -> Outputs:
        parsed = MESSAGES.parse("Pose_V", message.data)
        poses = poses_from_pose_v(parsed, self.options.robot_nums)
        return [(0, self.encoder.encode(poses))]
