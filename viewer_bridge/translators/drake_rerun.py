"""Drake's scene to Rerun: the scene once per load (static), every link's frame each draw.

`drake_to_rerun` reads a role's loads and draws: a load becomes an entity per link and one per
geometry (`viewer_bridge.formats.rerun.scene`), logged static so a viewer that connects later
gets it; a draw becomes one chunk of `Transform3D` rows, world -> every link's frame, at the
draw's time on the `sim_time` timeline and its receive time on `receive_time`
(`viewer_bridge.formats.rerun.transforms`). Frames are named as on ROS's /tf, role prefixes
included, so the illustration and proximity streams never share a frame; entities are rooted
at the role (`proximity/plant/iiwa/iiwa_link_0`) under the route's destination (`/drake`).

Beside it, what meldis shows besides the scene, each at its message's sim time:
`drake_images_to_rerun` (cameras: Image, DepthImage, SegmentationImage under a Pinhole),
`drake_point_cloud_to_rerun` (Points3D), `drake_draw_frames_to_rerun` (triads as Arrows3D),
`drake_contacts_to_rerun` (force and moment arrows, pressure-coloured surfaces).

Generic LCM channels (each numeric field as `Scalars` under `/lcm/<channel>/<field path>`) have
a translator of their own beside this one, reading the generic LCM message type
(`viewer_bridge.translators.lcm_rerun`).
"""

from __future__ import annotations

from typing import Any

import rerun as rr
from pydantic import Field

from viewer_bridge.errors import BridgeError
from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.drake.image import read_image_array, unpack
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm
from viewer_bridge.formats.rerun.chunks import Stamp, entity_path, static_chunk, timed_chunk
from viewer_bridge.formats.rerun.contact import contact_archetypes
from viewer_bridge.formats.rerun.image import image_archetype, pinhole
from viewer_bridge.formats.rerun.point_cloud import cloud_archetypes, frame_arrows
from viewer_bridge.formats.rerun.scene import scene_chunks
from viewer_bridge.formats.rerun.schema import Chunks
from viewer_bridge.formats.rerun.transforms import TransformsEncoder
from viewer_bridge.model.contact import ContactDrawOptions
from viewer_bridge.model.skipped import part_failed
from viewer_bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from viewer_bridge.translators.drake_stream import DrakeTranslator, DrawReader, role_of
from viewer_bridge.translators.options import CameraInfoOptions, FrameOptions
from viewer_bridge.translators.types import (
    CONTACT_TYPE,
    DRAW_TYPE,
    IMAGE_ARRAY_TYPE,
    POINT_CLOUD_TYPE,
    RERUN_CHUNKS_TYPE,
)
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
        parts = [] if scene is None else scene_chunks(scene, root, frames)
        if poses is not None:
            if self.encoder is None:  # one stream per translator: its role is its first channel's
                self.encoder = TransformsEncoder(entity_path(*root, "transforms"), frames, frames.world_frame)
            parts.append(self.encoder.encode(poses, Stamp.of(poses.timestamp_ms * 1000, message.received_us)))
        return [(0, Chunks.joined(parts))] if parts else []


_CAMERA_CHANNEL = "DRAKE_RGBD_CAMERA_IMAGES"


class RerunImagesOptions(TranslatorOptions):
    camera: str | None = None  # the camera's entity name; None: the channel's suffix ("camera" for none)
    camera_info: CameraInfoOptions | None = None  # a Pinhole above the images, from these intrinsics


class DrakeImagesToRerun(Translator):
    """`lcmt_image_array` -> each image under `/<camera>/<port>` (rgb, depth, label) at its sim time:
    `Image`, `DepthImage` (metres) or `SegmentationImage`, under the camera's `Pinhole` (static,
    once) when `camera_info` gives its intrinsics. An image that fails is counted alone."""

    Options = RerunImagesOptions
    options: RerunImagesOptions
    reads = (IMAGE_ARRAY_TYPE,)
    outputs = (Output("", RERUN_CHUNKS_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pinhole_sent = False

    def translate(self, message: Received) -> Outputs:
        suffix = message.channel.removeprefix(_CAMERA_CHANNEL).removeprefix("_")
        camera = self.options.camera or suffix or "camera"
        parts = []
        if self.options.camera_info is not None and not self._pinhole_sent:
            parts.append(static_chunk(entity_path(camera), [pinhole(self.options.camera_info.intrinsics())]))
            self._pinhole_sent = True
        for packed in read_image_array(message.data).images:
            try:
                image = unpack(packed)
                archetype = image_archetype(image)
            except BridgeError as error:  # a bad image (DecodeError) or one Rerun cannot show (SceneError)
                part_failed(error)
                continue
            stamp = Stamp.of(image.time_us, message.received_us)
            parts.append(timed_chunk(entity_path(camera, image.name), stamp, [archetype]))
        return [(0, Chunks.joined(parts))] if parts else []


class PointCloudOptions(TranslatorOptions):
    world_frame: str = ROOT_FRAME  # the frame of a cloud in Drake's world


class DrakePointCloudToRerun(Translator):
    """`lcmt_point_cloud` -> `Points3D` with its colours, in its frame, at its utime: the entity is
    the channel's suffix, lower case (DRAKE_POINT_CLOUD_FOO -> foo; none: the destination itself)."""

    Options = PointCloudOptions
    options: PointCloudOptions
    reads = (POINT_CLOUD_TYPE,)
    outputs = (Output("", RERUN_CHUNKS_TYPE),)

    def translate(self, message: Received) -> Outputs:
        stamped = cloud_from_lcm(message.data)
        name = message.channel.removeprefix("DRAKE_POINT_CLOUD").removeprefix("_").lower()
        stamp = Stamp.of(stamped.time_us, message.received_us)
        return [
            (0, timed_chunk(entity_path(name), stamp, cloud_archetypes(stamped, self.options.world_frame)))
        ]


class DrawFramesOptions(TranslatorOptions):
    length: float = Field(0.25, gt=0)  # of each axis, in metres (meldis draws 0.25 m)
    world_frame: str = ROOT_FRAME


class DrakeDrawFramesToRerun(DrawReader):
    """`lcmt_viewer_draw` of frames (DRAKE_DRAW_FRAMES) -> one `Arrows3D` of every frame's axes, at
    the draw's time (red x, green y, blue z, as meldis draws them)."""

    Options = DrawFramesOptions
    options: DrawFramesOptions
    reads = (DRAW_TYPE,)
    outputs = (Output("", RERUN_CHUNKS_TYPE),)

    def translate(self, message: Received) -> Outputs:
        poses = self.draw_poses(message)
        name = message.channel.removeprefix("DRAKE_DRAW_FRAMES").removeprefix("_").lower()
        stamp = Stamp.of(poses.timestamp_ms * 1000, message.received_us)
        archetypes = frame_arrows(poses, self.options.length, self.options.world_frame)
        return [(0, timed_chunk(entity_path(name), stamp, archetypes))]


class ContactOptions(TranslatorOptions, ContactDrawOptions):
    world_frame: str = ROOT_FRAME


class DrakeContactsToRerun(Translator):
    """`lcmt_contact_results_for_viz` -> `forces` and `moments` (Arrows3D) and `surfaces/<i>`
    (Mesh3D, pressure-coloured) at the results' time; a surface that ends is cleared."""

    Options = ContactOptions
    options: ContactOptions
    reads = (CONTACT_TYPE,)
    outputs = (Output("", RERUN_CHUNKS_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._surfaces = 0

    def translate(self, message: Received) -> Outputs:
        results = decode_contact_results(message.data)
        stamp = Stamp.of(results.timestamp_us, message.received_us)
        frame = rr.CoordinateFrame(self.options.world_frame)
        entities = contact_archetypes(results, self.options)
        parts = [
            timed_chunk(entity_path(*name.split("/")), stamp, [frame, *archetypes])
            for name, archetypes in entities.items()
        ]
        surfaces = sum(name.startswith("surfaces/") for name in entities)
        parts += [timed_chunk(entity_path("surfaces", str(index)), stamp, [rr.Clear(recursive=False)])
                  for index in range(surfaces, self._surfaces)]  # fmt: skip
        self._surfaces = surfaces
        return [(0, Chunks.joined(parts))]
