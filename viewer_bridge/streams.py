"""The streaming converters: one object per stream of messages, for many messages in a row.

`viewer_bridge.convert` converts one message per call and keeps nothing. These classes keep
what repeats from one frame to the next (a draw's link names, a message laid out once as a
template) and convert each new draw by writing only its numbers: keep one per stream (per
channel), and call it per message. Each lives in its format's module; they are gathered here
so that a user needs one import.

```python
from viewer_bridge.streams import DrawDecoder, PoseArrayEncoder

decoder, encoder = DrawDecoder(), PoseArrayEncoder("world")
for draw_bytes in draws:
    pose_array = encoder.encode(decoder.decode(draw_bytes))
```
"""

from __future__ import annotations

from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.foxglove.transforms import FrameTransformsEncoder
from viewer_bridge.formats.ign.poses import PosesEncoder
from viewer_bridge.formats.ros.markers import MarkerStream
from viewer_bridge.formats.ros.poses import PoseArrayEncoder
from viewer_bridge.formats.ros.tf import FrameNames, TransformsEncoder
from viewer_bridge.formats.tree_viewer.requests import SettransformEncoder
from viewer_bridge.formats.tree_viewer.tree import TreeState

__all__ = [
    "DrawDecoder",
    "DrawEncoder",
    "FrameNames",
    "FrameTransformsEncoder",
    "MarkerStream",
    "PoseArrayEncoder",
    "PosesEncoder",
    "SettransformEncoder",
    "TransformsEncoder",
    "TreeState",
]
