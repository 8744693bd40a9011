"""`import viewer_bridge.convert` is light: a fresh interpreter that imports it has loaded none of
the heavy modules its converters use and compiled no codec, and one call then still converts
(the modules it needs are imported by the call, and only those)."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.formats.ros import oracle as ros_oracle
from viewer_bridge.examples.demo import demo_poses, demo_scene
from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.ros.messages import to_cdr

# numpy and the codecs (lcmcodec.codecs compiles every LCM type's codec when it is imported) come with
# the first call; pydantic and yaml with the format tables; protobuf with ign and Foxglove; PIL
# with images; orjson with the tree viewer; rosbags with ROS message building.
HEAVY = ["numpy", "pydantic", "yaml", "google.protobuf", "PIL", "orjson", "rosbags", "viewer_bridge.lcmcodec.codecs",
         "viewer_bridge.formats.mappings", "viewer_bridge.model.scene"]  # fmt: skip

CHILD = """
import json, sys
import viewer_bridge.convert as convert
heavy = json.loads(sys.argv[1])
loaded_at_import = [name for name in heavy if name in sys.modules]
pose_array = convert.draw_to_pose_array(bytes.fromhex(sys.argv[2]), frame_id="map")
loaded_by_call = [name for name in heavy if name in sys.modules]
print(json.dumps({"loaded_at_import": loaded_at_import, "loaded_by_call": loaded_by_call, "pose_array": pose_array.hex()}))
"""


def test_importing_convert_loads_nothing_heavy_and_a_call_still_converts() -> None:
    draw = DrawEncoder().encode(demo_poses(demo_scene(), 0.5))
    result = subprocess.run([sys.executable, "-c", CHILD, json.dumps(HEAVY), draw.hex()],
                            capture_output=True, text=True, check=True)  # fmt: skip
    report = json.loads(result.stdout)
    assert report["loaded_at_import"] == []
    # A draw's PoseArray is written from the draw's arrays alone: no table, so no pydantic or
    # yaml, and nothing of protobuf or images.
    assert set(report["loaded_by_call"]) & {"pydantic", "yaml", "google.protobuf", "PIL"} == set()
    assert {"numpy", "viewer_bridge.lcmcodec.codecs"} <= set(report["loaded_by_call"])  # the call did import
    expected = to_cdr(ros_oracle.pose_array(DrawDecoder().decode(draw), "map"))
    assert bytes.fromhex(report["pose_array"]) == expected
