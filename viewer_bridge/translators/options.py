"""Options that several translator families share, as classes to inherit from.

Each is a `TranslatorOptions`: unknown keys are refused when the config loads. A translator's
own options class combines these (e.g. contact markers: `ContactDrawOptions` + `MarkerOptions`).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from viewer_bridge.errors import InvalidSetting
from viewer_bridge.formats.ign.schema import Package
from viewer_bridge.formats.ros.message_types import WORLD
from viewer_bridge.formats.ros.tf import FrameNames
from viewer_bridge.model.image import Intrinsics
from viewer_bridge.shared import Clock
from viewer_bridge.translators.base import TranslatorOptions
from viewer_bridge.translators.drake_stream import role_of
from viewer_bridge.translators.types import ign_type
from viewer_bridge.transports.base import MessageType


class MarkerOptions(TranslatorOptions):
    """The marker table's options (`mappings/ros.yaml`); unset ones keep the table's value."""

    frame_id: str | None = None
    embed_mesh_files: bool | None = None
    point_size: float | None = Field(None, gt=0)

    def table_overrides(self) -> dict[str, Any]:
        """The marker table's options that are set, whatever else a subclass adds."""
        return self.model_dump(include=set(MarkerOptions.model_fields), exclude_none=True)


class FrameOptions(TranslatorOptions):
    world_frame: str = WORLD  # the parent of every link frame (Drake's world link is this frame)
    frame_prefix: str | None = None  # None: by role ("" illustration, "proximity/", "perception/")

    def frames(self, channel: str) -> FrameNames:
        if self.frame_prefix is not None:
            return FrameNames(self.world_frame, self.frame_prefix)
        role = role_of(channel)
        return FrameNames(self.world_frame, "" if role in ("", "illustration") else f"{role}/")


class StampOptions(TranslatorOptions):
    """The clock a route's stamps are of: unset, the bridge's (the config's `time:`, receive time
    unless it says sim); `receive` or `sim` for this route only."""

    stamp: Literal["receive", "sim"] | None = None

    def sim_stamps(self, clock: Clock) -> bool:
        """Whether this route stamps with the message's sim time (else its receive time)."""
        return clock.sim if self.stamp is None else self.stamp == "sim"


class IgnOptions(TranslatorOptions):
    """The package of the route's ign/gz type names: unset, the ign transport's own (its `package`
    setting); `ignition` (Fortress, Debian's tools) or `gz` (Garden and later) for this route only."""

    package: Package | None = None

    def message_type(self, name: str) -> MessageType:
        return ign_type(name, self.package)


class CameraInfoOptions(BaseModel):
    """A camera's intrinsics: its size and a field of view in degrees (as Drake's `CameraConfig`
    gives it: vertical, horizontal or both), or focal lengths and principal point in pixels."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    width: int = Field(gt=0)
    height: int = Field(gt=0)
    fov_y: float | None = Field(None, gt=0, lt=180)
    fov_x: float | None = Field(None, gt=0, lt=180)
    fx: float | None = Field(None, gt=0)
    fy: float | None = Field(None, gt=0)
    cx: float | None = None  # None: the image's centre (width / 2 - 0.5), as Drake's
    cy: float | None = None

    @model_validator(mode="after")
    def _one_way(self) -> CameraInfoOptions:
        by_fov = self.fov_x is not None or self.fov_y is not None
        by_focal = self.fx is not None and self.fy is not None
        if by_fov == by_focal:
            raise InvalidSetting("give either fov_y (and/or fov_x), or fx and fy")
        return self

    def intrinsics(self) -> Intrinsics:
        if self.fx is not None and self.fy is not None:
            base = Intrinsics(
                self.width, self.height, self.fx, self.fy, self.width / 2 - 0.5, self.height / 2 - 0.5
            )
        else:
            base = Intrinsics.from_fov(self.width, self.height, self.fov_y, self.fov_x)
        cx = base.cx if self.cx is None else self.cx
        cy = base.cy if self.cy is None else self.cy
        return Intrinsics(base.width, base.height, base.fx, base.fy, cx, cy)
