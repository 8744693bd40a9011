"""The point cloud and draw-frames translators, called as the router calls them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from visualization_msgs.msg import MarkerArray

from tests.formats.drake.test_point_cloud import pydrake_message
from viewer_bridge.cli.log_convert import convert
from viewer_bridge.config.bridge import load_config
from viewer_bridge.errors import DecodeError
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.formats.tree_viewer.tree import TreeState
from viewer_bridge.model.scene import LinkPoses, PointCloud
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import Received
from viewer_bridge.transports.lcm import LcmEvent, write_log


def test_a_drake_cloud_becomes_a_tree_viewer_pointcloud_our_server_reads_back() -> None:
    translator = TRANSLATORS.get("drake_point_cloud_to_tree_viewer")()
    data = pydrake_message(("kXYZs", "kRGBs"), count=25)
    ((index, sent),) = translator.translate(Received("DRAKE_POINT_CLOUD_WRIST", data))
    request = envelope.decode(sent)
    (command,) = request["setgeometry"]
    assert index == 0 and command["path"] == ["point_clouds", "WRIST"]
    assert command["geometry"]["type"] == "pointcloud" and len(command["geometry"]["points"]) == 25
    state = TreeState()
    assert state.respond(request)["status"] == envelope.OK
    ((geometry,),) = [link.geometries for link in state.scene().links]
    assert isinstance(geometry.shape, PointCloud)
    assert geometry.shape == cloud_from_lcm(data).cloud  # points and colours, as Director gets them
    (_, unnamed), *_ = translator.translate(Received("DRAKE_POINT_CLOUD", data))
    assert envelope.decode(unnamed)["setgeometry"][0]["path"] == ["point_clouds", "default"]


def poses_of(names: tuple[str, ...]) -> bytes:
    count = len(names)
    quaternions = np.tile([1.0, 0.0, 0.0, 0.0], (count, 1))
    positions = np.arange(3.0 * count).reshape(count, 3)
    poses = LinkPoses(5, names, np.zeros(count, dtype=np.int32), positions, quaternions)
    return DrawEncoder().encode(poses)


def test_draw_frames_delete_all_only_when_the_frames_change() -> None:
    translator = TRANSLATORS.get("drake_draw_frames_to_markers")({"length": 0.5})
    arrays = []
    for names in (("a", "b"), ("a", "b"), ("a", "c::d")):
        ((_, data),) = translator.translate(Received("DRAKE_DRAW_FRAMES", poses_of(names)))
        arrays.append(deserialize_message(data, MarkerArray).markers)
    first, same, changed = arrays
    assert first[0].action == 3 and changed[0].action == 3  # DELETEALL, as meldis deletes old triads
    assert all(marker.action == 0 for marker in same)
    assert [marker.ns for marker in changed[1:]] == ["a", "c/d"]
    assert changed[2].pose.position.x == 3.0
    assert max(point.x for point in changed[2].points) == 0.5


def test_a_cloud_that_is_not_one_is_a_decode_error() -> None:
    with pytest.raises(DecodeError):
        TRANSLATORS.get("ros_point_cloud_to_drake")().translate(Received("/in", b"\x00\x01\x00\x00junk"))
    with pytest.raises(DecodeError):
        TRANSLATORS.get("drake_point_cloud_to_ros")().translate(Received("DRAKE_POINT_CLOUD", b"junk"))


def test_convert_carries_clouds_and_frames_of_a_log_into_an_mcap(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    log, out = tmp_path / "clouds.lcmlog", tmp_path / "clouds.mcap"
    cloud = pydrake_message(("kXYZs", "kRGBs"), count=12)
    write_log(
        log,
        [LcmEvent("DRAKE_POINT_CLOUD_WRIST", cloud, 1), LcmEvent("DRAKE_DRAW_FRAMES", poses_of(("a",)), 2)],
    )
    counts = convert(log, out, load_config(None), progress=False).messages
    assert counts == {"/drake/point_cloud/wrist": 1, "/drake/draw_frames": 1}
    with out.open("rb") as file:
        messages = {
            channel.topic: message
            for _, channel, _, message in make_reader(
                file, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages()
        }
    written = messages["/drake/point_cloud/wrist"]
    assert (written.width, written.point_step, written.fields[3].name) == (12, 16, "rgb")
    points = np.frombuffer(bytes(written.data), dtype=np.float32).reshape(12, 4)[:, :3]
    np.testing.assert_array_equal(points, cloud_from_lcm(cloud).cloud.points)
    assert [marker.ns for marker in messages["/drake/draw_frames"].markers] == ["", "a"]  # DELETEALL, triad
