"""Camera images as Rerun archetypes: colour as `Image`, depth as `DepthImage` in metres, labels as
`SegmentationImage`, and the camera's `Pinhole` from its intrinsics.

Pixels go as they are (no copy but a byte-order swap for big-endian data): a 16-bit depth image
says its unit with `meter` (Drake's millimetres: 1000 per metre), a float one is metres already.
Drake's labels are signed 16-bit; Rerun's class ids are unsigned, so a label is read as its
16-bit pattern (Drake's reserved negative labels become 65535 down, each still one class).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from viewer_bridge.errors import SceneError
from viewer_bridge.model.image import MILLIMETRES_PER_METRE, Image, Intrinsics, Layout

_COLOR_MODELS = {
    Layout.GRAY: rr.ColorModel.L,
    Layout.RGB: rr.ColorModel.RGB,
    Layout.RGBA: rr.ColorModel.RGBA,
    Layout.BGR: rr.ColorModel.BGR,
    Layout.BGRA: rr.ColorModel.BGRA,
}


def image_archetype(image: Image) -> Any:
    """The archetype of one image; `SceneError` for a layout Rerun has no image for (Bayer, mask)."""
    pixels = image.pixels.astype(image.pixels.dtype.newbyteorder("=")) if image.big_endian else image.pixels
    if image.layout in _COLOR_MODELS:
        return rr.Image(pixels, color_model=_COLOR_MODELS[image.layout])
    if image.layout == Layout.DEPTH:
        meter = MILLIMETRES_PER_METRE if pixels.dtype == np.uint16 else 1.0
        return rr.DepthImage(pixels[:, :, 0] if pixels.ndim == 3 else pixels, meter=meter)
    if image.layout == Layout.LABEL:
        labels = pixels[:, :, 0] if pixels.ndim == 3 else pixels
        return rr.SegmentationImage(labels.view(np.uint16) if labels.dtype == np.int16 else labels)
    raise SceneError(f"image {image.name}: Rerun has no image of layout {image.layout.value}")


def pinhole(intrinsics: Intrinsics) -> rr.Pinhole:
    """The camera's projection (x right, y down, z forward, as Drake's cameras look)."""
    return rr.Pinhole(
        focal_length=[intrinsics.fx, intrinsics.fy],
        principal_point=[intrinsics.cx + 0.5, intrinsics.cy + 0.5],  # Rerun: the first pixel's corner at 0
        width=intrinsics.width,
        height=intrinsics.height,
        camera_xyz=rr.ViewCoordinates.RDF,
    )
