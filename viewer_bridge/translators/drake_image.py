"""Drake's camera images (`lcmt_image_array`, DRAKE_RGBD_CAMERA_IMAGES*) to ROS 2 and Foxglove, and back.

`drake_images_to_ros`: each image of an array (one per port of Drake's publisher: rgb, depth,
label) becomes a `sensor_msgs/Image` on `<destination>/<port>/image`; by option a
`CompressedImage` on `<port>/image/compressed` (JPEG or PNG bytes Drake sent pass as they are,
others are encoded) and a `CameraInfo` on `<port>/camera_info`, named as image_transport names
them. A camera's ports are known only from its messages, so the outputs are added as ports
appear (the router looks an output up by its index, and asks each for subscribers); the types
they may have are declared from the options (`writes`), for the checks at load and start. An image
that does not decode is counted as the route's error (`viewer_bridge.model.skipped.part_failed`); the other
images of the array still go out.

`drake_images_to_foxglove`: the same as `foxglove.RawImage` on `<destination>/<port>/image`, by
option `foxglove.CompressedImage` on `<port>/compressed` and `foxglove.CameraCalibration` on
`<port>/calibration`, for Foxglove's Image panel. Both stamp as the scene's frames are stamped:
by the bridge's clock (the config's `time:`), the image's utime with `time: sim`, else its receive time.

`ros_image_to_drake`: a `sensor_msgs/Image` -> an `lcmt_image_array` of that one image, which
Drake's `LcmImageArrayToImages` reads (bgr8 and bgra8 reordered to RGB, float depth in Drake's
conventions, zlib unless told not to).

An array is read and its images unpacked once for every route that reads it (`image_array`,
`unpacked_images`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, ClassVar, Literal

from viewer_bridge.errors import BridgeError, DecodeError, EncodeError
from viewer_bridge.formats.drake.image import ImageArray, images_to_lcm, read_image_array, unpack
from viewer_bridge.formats.foxglove import image as foxglove_image
from viewer_bridge.formats.ros.cdr import time_parts_from_us
from viewer_bridge.formats.ros.image import (
    CAMERA_INFO,
    COMPRESSED_IMAGE,
    IMAGE,
    CameraInfoEncoder,
    compressed_image_to_cdr,
    image_from_cdr,
    image_to_cdr,
)
from viewer_bridge.model.image import (
    EncodedImage,
    FileFormat,
    Image,
    Intrinsics,
    Layout,
    depth_from_rep117,
    depth_rep117,
    encode_file,
)
from viewer_bridge.model.skipped import part_failed
from viewer_bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from viewer_bridge.translators.options import CameraInfoOptions, StampOptions
from viewer_bridge.translators.types import (
    CAMERA_CALIBRATION_TYPE,
    COMPRESSED_IMAGE_TYPE,
    IMAGE_ARRAY_TYPE,
    RAW_IMAGE_TYPE,
    ros_type,
)
from viewer_bridge.transports.base import MessageType, Received
from viewer_bridge.transports.ros_names import name_token

CAMERA_CHANNEL = "DRAKE_RGBD_CAMERA_IMAGES"  # ApplyCameraConfig appends _<camera name>
UNNAMED_CAMERA = "camera"  # the camera of the plain DRAKE_RGBD_CAMERA_IMAGES channel


def _read(message: Received) -> ImageArray:
    return read_image_array(message.data)


def image_array(message: Received) -> ImageArray:
    """A received `lcmt_image_array`, its images still packed, read once for every route."""
    return message.decoded(_read)


def _unpack_all(message: Received) -> tuple[Image | DecodeError, ...]:
    results: list[Image | DecodeError] = []
    for packed in image_array(message).images:
        try:
            results.append(unpack(packed))
        except DecodeError as error:
            results.append(error)
    return tuple(results)


def unpacked_images(message: Received) -> tuple[Image | DecodeError, ...]:
    """Each image's pixels, or why it has none, decoded once for every route."""
    return message.decoded(_unpack_all)


def camera_name(channel: str) -> str:
    """The camera of an image channel: `DRAKE_RGBD_CAMERA_IMAGES_left` -> `left`."""
    return channel.removeprefix(CAMERA_CHANNEL).removeprefix("_") or UNNAMED_CAMERA


class ImagesOptions(StampOptions):
    """Stamps (`stamp`): the image's utime (sim time) or its receive time, as the bridge's clock says."""

    frame_id: str | None = None  # None: the camera's name (the channel's suffix; "camera" for none)
    drop_alpha: bool = False  # rgba8 -> rgb8, bgra8 -> bgr8
    depth: Literal["16UC1", "32FC1"] = "16UC1"  # 32FC1: metres, REP 117 (a float depth image always is)
    # Also a compressed image: Drake's JPEG or PNG as they came, the others encoded in this format.
    compressed: FileFormat | None = None
    camera_info: CameraInfoOptions | None = None  # also the intrinsics beside each image of this size


class FoxgloveImagesOptions(ImagesOptions):
    """As the ROS images' (stamped by the bridge's clock, as the scene's transforms: they sync)."""


@dataclass(slots=True)
class _Port:
    """Where one port's messages go: indices into the translator's outputs."""

    image: int
    compressed: int | None
    info: int | None


class _DrakeImages(Translator):
    """The camera translators' common part: ports become outputs as they appear, each image is
    written by the target's `write_*` (the subclass's), one that fails is counted alone."""

    Options = ImagesOptions
    options: ImagesOptions
    reads = (IMAGE_ARRAY_TYPE,)
    # The suffixes (after /<port>) and types of what each port publishes.
    IMAGE: ClassVar[tuple[str, MessageType]]
    COMPRESSED: ClassVar[tuple[str, MessageType]]
    INFO: ClassVar[tuple[str, MessageType]]

    outputs: tuple[Output, ...] = ()  # per instance: its ports', added as they appear

    @classmethod
    def writes(cls, options: TranslatorOptions) -> tuple[MessageType, ...]:
        """Each port's image, and its compressed image and intrinsics when the options ask for them."""
        assert isinstance(options, ImagesOptions)
        asked = (
            cls.IMAGE,
            cls.COMPRESSED if options.compressed else None,
            cls.INFO if options.camera_info else None,
        )
        return tuple(message_type for _, message_type in filter(None, asked))

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._ports: dict[str, _Port] = {}
        self._intrinsics = self.options.camera_info.intrinsics() if self.options.camera_info else None
        self._sim = self.options.sim_stamps(self.shared.clock)

    def write_image(self, image: Image, frame_id: str, stamp: tuple[int, int]) -> bytes:
        raise NotImplementedError

    def write_compressed(self, image: EncodedImage, frame_id: str, stamp: tuple[int, int]) -> bytes:
        raise NotImplementedError

    def write_info(self, intrinsics: Intrinsics, frame_id: str, stamp: tuple[int, int]) -> bytes:
        raise NotImplementedError

    def observe(self, message: Received) -> None:
        try:
            for packed in image_array(message).images:
                self._port(packed.name)
        except DecodeError:
            return  # translate raises it, and the route counts it (when it translates)

    def _port(self, name: str) -> _Port:
        port = self._ports.get(name)
        if port is None:
            port = self._ports[name] = _Port(
                self._add(name, self.IMAGE),
                self._add(name, self.COMPRESSED) if self.options.compressed else None,
                self._add(name, self.INFO) if self._intrinsics else None,
            )
        return port

    def _add(self, port: str, output: tuple[str, MessageType]) -> int:
        suffix, message_type = output
        self.outputs = (*self.outputs, Output(f"/{name_token(port)}/{suffix}", message_type))
        return len(self.outputs) - 1

    def translate(self, message: Received) -> Outputs:
        array = image_array(message)
        frame_id = self.options.frame_id or camera_name(message.channel)
        out: Outputs = []
        for packed, image in zip(array.images, unpacked_images(message), strict=True):
            try:
                if isinstance(image, DecodeError):
                    raise image
                time_us = image.time_us if self._sim else message.received_us
                stamp = time_parts_from_us(time_us)
                port = self._port(packed.name)
                out.append((port.image, self.write_image(self._as_options_say(image), frame_id, stamp)))
                if port.compressed is not None and self.options.compressed is not None:
                    encoded = packed.encoded() or encode_file(image, self.options.compressed)
                    out.append((port.compressed, self.write_compressed(encoded, frame_id, stamp)))
                if port.info is not None:
                    out.append((port.info, self.write_info(self._intrinsics_of(image), frame_id, stamp)))
            except BridgeError as error:
                part_failed(error)  # counted on the route; the other images still go out
        return out

    def _as_options_say(self, image: Image) -> Image:
        """Alpha dropped, depth in metres, as the options say."""
        if self.options.drop_alpha:
            image = image.without_alpha()
        if image.layout is Layout.DEPTH and (self.options.depth == "32FC1" or image.pixels.dtype.kind == "f"):
            image = depth_rep117(image)
        return image

    def _intrinsics_of(self, image: Image) -> Intrinsics:
        intrinsics = self._intrinsics
        assert intrinsics is not None
        if (image.width, image.height) != (intrinsics.width, intrinsics.height):
            raise EncodeError(
                self.INFO[1].name,
                "width",
                f"image {image.name!r} is {image.width} x {image.height}, camera_info is for "
                f"{intrinsics.width} x {intrinsics.height}",
            )
        return intrinsics


class DrakeImagesToRos(_DrakeImages):
    """`lcmt_image_array` -> per image a `sensor_msgs/Image` (+ CompressedImage, CameraInfo)."""

    IMAGE = ("image", ros_type(IMAGE))
    COMPRESSED = ("image/compressed", ros_type(COMPRESSED_IMAGE))  # image_transport's names
    INFO = ("camera_info", ros_type(CAMERA_INFO))

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._info: CameraInfoEncoder | None = None

    def write_image(self, image: Image, frame_id: str, stamp: tuple[int, int]) -> bytes:
        return image_to_cdr(image, frame_id, stamp)

    def write_compressed(self, image: EncodedImage, frame_id: str, stamp: tuple[int, int]) -> bytes:
        return compressed_image_to_cdr(image, frame_id, stamp)

    def write_info(self, intrinsics: Intrinsics, frame_id: str, stamp: tuple[int, int]) -> bytes:
        if self._info is None or self._info.frame_id != frame_id:  # made once, stamped per image
            self._info = CameraInfoEncoder(intrinsics, frame_id)
        return self._info.encode(stamp)


class DrakeImagesToFoxglove(_DrakeImages):
    """`lcmt_image_array` -> per image a `foxglove.RawImage` (+ CompressedImage, CameraCalibration)
    for Foxglove's Image panel; stamped with Drake's sim time by default, as the scene's frames."""

    Options = FoxgloveImagesOptions
    options: FoxgloveImagesOptions
    IMAGE = ("image", RAW_IMAGE_TYPE)
    COMPRESSED = ("compressed", COMPRESSED_IMAGE_TYPE)
    INFO = ("calibration", CAMERA_CALIBRATION_TYPE)

    def write_image(self, image: Image, frame_id: str, stamp: tuple[int, int]) -> bytes:
        return foxglove_image.raw_image(image, frame_id, stamp)

    def write_compressed(self, image: EncodedImage, frame_id: str, stamp: tuple[int, int]) -> bytes:
        return foxglove_image.compressed_image(image, frame_id, stamp)

    def write_info(self, intrinsics: Intrinsics, frame_id: str, stamp: tuple[int, int]) -> bytes:
        return foxglove_image.camera_calibration(intrinsics, frame_id, stamp)


class RosImageToDrakeOptions(TranslatorOptions):
    name: str | None = None  # the image's frame_name in the array; None: rgb, depth, label, gray ...
    # zlib, as ImageToLcmImageArrayT's do_compress (on by default there too). Drake 1.51's
    # LcmImageArrayToImages reads uncompressed 16- and 32-bit images only in part (docs/PROTOCOLS.md
    # section 10): its zlib path reads them whole.
    compress: bool = True


# Drake 1.51's LcmImageArrayToImages reads the first colour image of an array as 8-bit RGB(A), and
# aborts its process on BGR or on 16-bit colour (docs/PROTOCOLS.md section 12): BGR is sent as RGB,
# 16-bit colour is refused.
_PORT_NAMES = {Layout.RGB: "rgb", Layout.BGR: "rgb", Layout.RGBA: "rgb", Layout.BGRA: "rgb"}


class RosImageToDrake(Translator):
    """`sensor_msgs/Image` -> `lcmt_image_array` of one image, laid out as Drake's
    `ImageToLcmImageArrayT` lays it out; the ROS frame_id is the array's frame_name, the stamp
    its utime; BGR as RGB, 16-bit colour refused; 32FC1 depth with REP 117's -inf and NaN becomes Drake's 0 and +inf."""

    Options = RosImageToDrakeOptions
    options: RosImageToDrakeOptions
    reads = (ros_type(IMAGE),)
    outputs = (Output("", IMAGE_ARRAY_TYPE),)

    def translate(self, message: Received) -> Outputs:
        stamped = image_from_cdr(message.data)
        image = depth_from_rep117(stamped.image).rgb_order()
        if image.layout in _PORT_NAMES and image.pixels.dtype.itemsize != 1:
            raise EncodeError(
                IMAGE_ARRAY_TYPE.name,
                "images.channel_type",
                "16-bit colour, on which LcmImageArrayToImages aborts",
            )
        name = self.options.name or _PORT_NAMES.get(image.layout, image.layout.value)
        image = replace(image, name=name)
        return [(0, images_to_lcm([image], stamped.time_us, self.options.compress, stamped.frame_id))]
