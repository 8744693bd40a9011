"""Make docs/camera_images.png: the colour, depth and label images of the test scene, side by side.

Run: .venv/bin/python docs/camera_images.py

Drake renders viewer_bridge/examples/cameras.py (RenderEngineVtk) and ApplyCameraConfig publishes the
three images as one zlib-compressed lcmt_image_array, on an in-process LCM; the bridge's own code
reads it (`viewer_bridge.formats.drake.image`) and draws each image for a person to look at
(`viewer_bridge.model.image.preview`: depth as grey, near is light; labels a colour each).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image as PilImage

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # tests/ (the camera scene)

from viewer_bridge.formats.drake.image import read_image_array, unpack  # noqa: E402
from viewer_bridge.model.image import preview  # noqa: E402

GAP = 6  # white pixels between the pictures


def main() -> None:
    from pydrake.lcm import DrakeLcm

    from viewer_bridge.examples.cameras import build_simulator

    lcm = DrakeLcm("memq://")
    sent: list[bytes] = []
    lcm.SubscribeAllChannels(lambda channel, data: sent.append(bytes(data)))
    build_simulator(lcm, {"docs": (480, 360, True)}).AdvanceTo(0.0)
    while lcm.HandleSubscriptions(0):
        pass
    images = {packed.name: unpack(packed) for packed in read_image_array(sent[0]).images}
    pictures = [preview(images[port]) for port in ("rgb", "depth", "label")]
    height = pictures[0].shape[0]
    gap = np.full((height, GAP, 3), 255, np.uint8)
    row = np.concatenate([part for picture in pictures for part in (picture, gap)][:-1], axis=1)
    PilImage.fromarray(row).save(HERE / "camera_images.png", optimize=True)
    print(f"wrote {HERE / 'camera_images.png'}: {row.shape[1]} x {row.shape[0]}")


if __name__ == "__main__":
    main()
