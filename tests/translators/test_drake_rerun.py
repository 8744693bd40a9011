"""Drake's camera images to Rerun: the bytes Drake's own `ImageToLcmImageArrayT` publishes, through
`drake_images_to_rerun` and the rerun transport into an .rrd file, read back with Rerun's reader:
the pixels Drake sent, depth in metres, labels as classes, under the camera's Pinhole."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest
from rerun.chunk import RrdReader

from tests.conftest import EXAMPLES, lcm_url, record_log
from tests.drake_images import publish_with_drake
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.point_cloud import cloud_to_lcm
from viewer_bridge.model.scene import LinkPoses, PointCloud, StampedPointCloud
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.translators.types import RERUN_CHUNKS_TYPE
from viewer_bridge.transports.base import Qos, Received, hand_over
from viewer_bridge.transports.lcm import read_log
from viewer_bridge.transports.rerun import RerunSettings, RerunTransport

CONTACT_SCENE = EXAMPLES / "contacts.py"


def _rows(path: Path) -> dict[str, dict[str, Any]]:
    rows = {}
    for chunk in RrdReader(path).stream():
        for row in chunk.to_record_batch().to_pylist():
            rows.setdefault(chunk.entity_path, {}).update(row)
    return rows


@pytest.mark.parametrize("compress", [False, True])
def test_drakes_images_reach_rerun_with_drakes_pixels(tmp_path: Path, compress: bool) -> None:
    rng = np.random.default_rng(5)
    rgba = rng.integers(0, 256, (6, 8, 4), dtype=np.uint8)
    depth = rng.integers(0, 5000, (6, 8, 1), dtype=np.uint16)
    label = rng.integers(-2, 40, (6, 8, 1), dtype=np.int16)
    ports = [("rgb", "rgba8", rgba), ("depth", "depth16", depth), ("label", "label16", label)]
    data = publish_with_drake(ports, 1.5, compress)
    options = {"camera_info": {"width": 8, "height": 6, "fov_y": 90}}
    translator = TRANSLATORS["drake_images_to_rerun"](options)
    transport = RerunTransport(RerunSettings(path=tmp_path / "images.rrd"))
    publisher = transport.publisher("/drake/cameras", RERUN_CHUNKS_TYPE, Qos())
    for _, payload in translator.translate(Received("DRAKE_RGBD_CAMERA_IMAGES_left", data)):
        hand_over(publisher, payload)
    transport.close()
    rows = _rows(tmp_path / "images.rrd")
    rgb = rows["/drake/cameras/left/rgb"]
    assert bytes(rgb["Image:buffer"][0]) == rgba.tobytes()
    depth_row = rows["/drake/cameras/left/depth"]
    assert bytes(depth_row["DepthImage:buffer"][0]) == depth.tobytes()
    assert depth_row["DepthImage:meter"] == [1000.0]  # Drake's millimetres
    assert bytes(rows["/drake/cameras/left/label"]["SegmentationImage:buffer"][0]) == label.tobytes()
    assert rgb["sim_time"].total_seconds() == 1.5
    pinhole = rows["/drake/cameras/left"]
    assert pinhole["Pinhole:resolution"] == [[8.0, 6.0]]
    assert np.isclose(pinhole["Pinhole:image_from_camera"][0][0], 3.0)  # fx = height / 2 / tan(45 deg)


def _through_file(
    tmp_path: Path, translator_name: str, channel: str, data: bytes, destination: str
) -> dict[str, Any]:
    translator = TRANSLATORS[translator_name]({})
    transport = RerunTransport(RerunSettings(path=tmp_path / "out.rrd"))
    publisher = transport.publisher(destination, RERUN_CHUNKS_TYPE, Qos())
    for _, payload in translator.translate(Received(channel, data)):
        hand_over(publisher, payload)
    transport.close()
    return _rows(tmp_path / "out.rrd")


def test_a_point_cloud_is_points_with_its_colours(tmp_path: Path) -> None:
    points = np.array([[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]])
    colors = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    data = cloud_to_lcm(StampedPointCloud(PointCloud(points, colors), "world", 2_000_000))
    rows = _through_file(
        tmp_path, "drake_point_cloud_to_rerun", "DRAKE_POINT_CLOUD_FOO", data, "/drake/point_cloud"
    )
    row = rows["/drake/point_cloud/foo"]
    assert np.allclose(row["Points3D:positions"], points)
    assert row["Points3D:colors"] == [0xFF0000FF, 0x00FF00FF]
    assert row["CoordinateFrame:frame"] == ["tf#/"]
    assert row["sim_time"].total_seconds() == 2.0


def test_draw_frames_are_triads(tmp_path: Path) -> None:
    poses = LinkPoses(
        500, ("a", "b"), np.zeros(2, np.int32), np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]),
        np.array([[1.0, 0.0, 0.0, 0.0], [np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)]]),
    )  # fmt: skip
    data = DrawEncoder().encode(poses)
    rows = _through_file(
        tmp_path, "drake_draw_frames_to_rerun", "DRAKE_DRAW_FRAMES", data, "/drake/draw_frames"
    )
    row = rows["/drake/draw_frames"]
    vectors = np.array(row["Arrows3D:vectors"])
    assert np.allclose(row["Arrows3D:origins"], [[0, 0, 0]] * 3 + [[1, 2, 3]] * 3)
    assert np.allclose(vectors[:3], np.eye(3) * 0.25, atol=1e-6)
    assert np.allclose(vectors[3], [0.0, 0.25, 0.0], atol=1e-6)  # b turned 90 degrees about z: x along y


@pytest.fixture(scope="module")
def contact_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A pydrake simulation with point and hydroelastic contact, recorded by lcm-logger."""
    folder = tmp_path_factory.mktemp("contacts")
    url = lcm_url(33)
    return record_log(folder / "contacts.lcmlog", url, [sys.executable, str(CONTACT_SCENE), url, "0.3", "0"])


def test_drakes_contacts_are_arrows_and_pressure_coloured_surfaces(tmp_path: Path, contact_log: Path) -> None:
    data = [event.data for event in read_log(contact_log, "CONTACT_RESULTS")][-1]
    last = drake_lcmtypes.lcmt_contact_results_for_viz.decode(data)
    assert last.num_point_pair_contacts and last.num_hydroelastic_contacts  # both kinds, from Drake
    rows = _through_file(tmp_path, "drake_contacts_to_rerun", "CONTACT_RESULTS", data, "/drake/contacts")
    forces = [list(p.contact_force) for p in last.point_pair_contact_info] + [
        list(h.force_C_W) for h in last.hydroelastic_contacts
    ]
    vectors = np.array(rows["/drake/contacts/forces"]["Arrows3D:vectors"])
    assert np.allclose(vectors, np.array(forces) * 0.01, atol=1e-5)  # force_scale: 0.01 m/N
    surface = last.hydroelastic_contacts[0]
    mesh = rows["/drake/contacts/surfaces/0"]
    assert len(mesh["Mesh3D:vertex_positions"]) == surface.num_vertices
    assert len(mesh["Mesh3D:vertex_colors"]) == surface.num_vertices
    assert len(set(mesh["Mesh3D:vertex_colors"])) > 1  # coloured by pressure, not one colour
