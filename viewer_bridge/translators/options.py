"""Options that several translator families share, as classes to inherit from.

Each is a `TranslatorOptions`: unknown keys are refused when the config loads. A translator's
own options class combines these (e.g. contact markers: `ContactDrawOptions` + `MarkerOptions`).
"""

from __future__ import annotations

from typing import Any

from pydantic import Field

from viewer_bridge.formats.ign.schema import Package
from viewer_bridge.formats.ros.tf import WORLD, FrameNames
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


class IgnOptions(TranslatorOptions):
    """The package of the route's ign/gz type names: unset, the ign transport's own (its `package`
    setting); `ignition` (Fortress, Debian's tools) or `gz` (Garden and later) for this route only."""

    package: Package | None = None

    def message_type(self, name: str) -> MessageType:
        return ign_type(name, self.package)


__all__ = [
    "FrameOptions",
    "IgnOptions",
    "MarkerOptions",
]
