"""Drake's own image systems as oracles: `ImageToLcmImageArrayT` writes, `LcmImageArrayToImages` reads.

Both run in a pydrake diagram with Drake's C++ LCM serializer on an in-process LCM (`memq://`),
so what the tests compare against is exactly what a Drake simulation sends and reads.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tests.optional import peer

drake_lcmtypes = peer("drake")

# Drake's pixel types by the names tests use: (PixelType member, its Image class name).
PIXEL_TYPES = {
    "rgba8": ("kRgba8U", "ImageRgba8U"),
    "rgb8": ("kRgb8U", "ImageRgb8U"),
    "bgr8": ("kBgr8U", "ImageBgr8U"),
    "bgra8": ("kBgra8U", "ImageBgra8U"),
    "grey8": ("kGrey8U", "ImageGrey8U"),
    "depth16": ("kDepth16U", "ImageDepth16U"),
    "depth32": ("kDepth32F", "ImageDepth32F"),
    "label16": ("kLabel16I", "ImageLabel16I"),
}
CHANNEL = "IMAGES"


def drake_image(kind: str, pixels: np.ndarray) -> Any:
    """A pydrake Image of `kind` (a key of PIXEL_TYPES) holding `pixels` (height x width x channels)."""
    from pydrake.systems import sensors

    image = getattr(sensors, PIXEL_TYPES[kind][1])(pixels.shape[1], pixels.shape[0])
    image.mutable_data[:] = pixels
    return image


def publish_with_drake(images: list[tuple[str, str, np.ndarray]], time_s: float, compress: bool) -> bytes:
    """The `lcmt_image_array` bytes ImageToLcmImageArrayT publishes for (port name, kind, pixels)."""
    from pydrake.lcm import DrakeLcm
    from pydrake.systems import sensors
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.lcm import LcmPublisherSystem

    lcm = DrakeLcm("memq://")
    sent: list[bytes] = []
    lcm.Subscribe(CHANNEL, lambda data: sent.append(bytes(data)))
    builder = DiagramBuilder()
    to_lcm = builder.AddSystem(sensors.ImageToLcmImageArrayT(do_compress=compress))
    for name, kind, _ in images:
        port = to_lcm.DeclareImageInputPort[getattr(sensors.PixelType, PIXEL_TYPES[kind][0])](name)
        builder.ExportInput(port)
    publisher = builder.AddSystem(
        LcmPublisherSystem.Make(
            channel=CHANNEL,
            lcm_type=drake_lcmtypes.lcmt_image_array,
            lcm=lcm,
            publish_period=0.0,
            use_cpp_serializer=True,
        )
    )
    builder.Connect(to_lcm.get_output_port(), publisher.get_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    context.SetTime(time_s)
    for index, (_, kind, pixels) in enumerate(images):
        diagram.get_input_port(index).FixValue(context, drake_image(kind, pixels))
    diagram.ForcedPublish(context)
    while lcm.HandleSubscriptions(0):
        pass
    assert len(sent) == 1
    return sent[0]


def read_with_drake(data: bytes) -> dict[str, np.ndarray]:
    """What Drake's LcmImageArrayToImages makes of the bytes: `color_image` (RGBA8U),
    `depth_image` (Depth32F metres) and `label_image` (Label16I), each height x width x channels
    (0 x 0 when the array has none of that kind)."""
    from pydrake.lcm import DrakeLcm
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.lcm import LcmSubscriberSystem
    from pydrake.systems.sensors import LcmImageArrayToImages

    lcm = DrakeLcm("memq://")
    builder = DiagramBuilder()
    subscriber = builder.AddSystem(
        LcmSubscriberSystem.Make(
            channel=CHANNEL, lcm_type=drake_lcmtypes.lcmt_image_array, lcm=lcm, use_cpp_serializer=True
        )
    )
    to_images = builder.AddSystem(LcmImageArrayToImages())
    builder.Connect(subscriber.get_output_port(), to_images.get_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    lcm.Publish(CHANNEL, data)
    while lcm.HandleSubscriptions(0):
        pass
    diagram.ExecuteForcedEvents(context)  # the subscriber takes the message into its state
    own = to_images.GetMyContextFromRoot(context)
    ports = ("color_image", "depth_image", "label_image")
    return {port: np.array(to_images.GetOutputPort(port).Eval(own).data) for port in ports}
