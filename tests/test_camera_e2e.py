"""Camera images end to end: a pydrake simulation with ApplyCameraConfig (colour, depth and label;
one camera compressed, one not), the bridge as a process on its built-in config (with camera_info
options), rclpy on the other side; and rclpy images back to what Drake's own reader reads."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest
import yaml

from tests.conftest import EXAMPLES, lcm_url
from tests.drake_images import read_with_drake
from tests.peers import BridgeProcess, RosProbe
from tests.test_router import LcmRecorder
from tests.translators.test_drake_image import assert_drake_reads, ros_test_image
from viewer_bridge.config.bridge import DEFAULT_CONFIG
from viewer_bridge.examples.cameras import CAMERAS, FOV_Y_DEGREES

pytestmark = [pytest.mark.slow, pytest.mark.e2e]

SCENE = EXAMPLES / "cameras.py"
PORTS = ("rgb", "depth", "label")
WIDTH, HEIGHT, _ = CAMERAS["left"]
ENCODINGS = {"rgb": "rgba8", "depth": "16UC1", "label": "16SC1"}
DTYPES = {"rgb": "u1", "depth": "<u2", "label": "<i2"}


@pytest.fixture
def probe() -> Any:
    node = RosProbe()
    yield node
    node.close()


def default_config_with_camera_info(folder: Path) -> Path:
    """The built-in config, its camera route given the cameras' intrinsics."""
    config = yaml.safe_load(DEFAULT_CONFIG)
    (route,) = [route for route in config["routes"] if route["name"] == "camera_images"]
    route["options"] = {"camera_info": {"width": WIDTH, "height": HEIGHT, "fov_y": FOV_Y_DEGREES}}
    path = folder / "bridge.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


def drake_pixels(data: bytes, port: str) -> np.ndarray:
    """A port's pixels as Drake reads them: its LcmImageArrayToImages for what it reads whole (depth
    in metres), else (uncompressed 16-bit rows, docs/PROTOCOLS.md section 12) Drake's class."""
    message = drake_lcmtypes.lcmt_image_array.decode(data)
    (image,) = [image for image in message.images if image.header.frame_name == port]
    if port == "rgb" or image.compression_method == drake_lcmtypes.lcmt_image.COMPRESSION_METHOD_ZLIB:
        return read_with_drake(data)[
            {"rgb": "color_image", "depth": "depth_image", "label": "label_image"}[port]
        ]
    return np.frombuffer(image.data, DTYPES[port]).reshape(image.height, image.width, 1)


def as_drake_reads(message: Any, port: str, compressed: bool) -> np.ndarray:
    """A ROS image's pixels in the form `drake_pixels` gives for its port."""
    pixels = np.frombuffer(bytes(message.data), DTYPES[port]).reshape(message.height, message.width, -1)
    if port == "depth" and compressed:  # Drake's reader divides as float(mm) / 1e3 in double
        return (pixels.astype(np.float64) / 1e3).astype(np.float32)
    return pixels


def test_drake_cameras_reach_rclpy_with_drakes_pixels_and_camera_info(
    probe: RosProbe, tmp_path: Path
) -> None:
    url = lcm_url(23)
    images = {
        (camera, port): probe.subscribe(
            f"/drake/cameras/{camera}/{port}/image", "sensor_msgs/msg/Image", depth=5
        )
        for camera in CAMERAS
        for port in PORTS
    }
    infos = {
        (camera, port): probe.subscribe(
            f"/drake/cameras/{camera}/{port}/camera_info", "sensor_msgs/msg/CameraInfo"
        )
        for camera in CAMERAS
        for port in PORTS
    }
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--config", str(default_config_with_camera_info(tmp_path)), "--lcm-url", url)
    simulation: subprocess.Popen[bytes] | None = None
    started_us = time.time_ns() // 1000
    try:
        bridge.wait_for_line(" running (")
        simulation = subprocess.Popen([sys.executable, str(SCENE), url, "120"])

        def arrived() -> bool:
            channels = all(recorder.messages.get(f"DRAKE_RGBD_CAMERA_IMAGES_{camera}") for camera in CAMERAS)
            return channels and all(images.values()) and all(infos.values())

        assert probe.wait_for(arrived, timeout=90), bridge.lines
    finally:
        if simulation is not None:
            simulation.terminate()
            simulation.wait(timeout=30)
        assert bridge.stop() == 0
        recorder.close()
    ended_us = time.time_ns() // 1000
    for camera, (_, _, compressed) in CAMERAS.items():
        sent = recorder.messages[f"DRAKE_RGBD_CAMERA_IMAGES_{camera}"]
        for port in PORTS:
            message = images[camera, port][-1]
            assert (message.width, message.height, message.encoding) == (WIDTH, HEIGHT, ENCODINGS[port])
            assert message.header.frame_id == camera and not message.is_bigendian
            stamp_us = message.header.stamp.sec * 1_000_000 + message.header.stamp.nanosec // 1000
            assert started_us <= stamp_us <= ended_us  # the bridge's receive time (the default)
            got = as_drake_reads(message, port, compressed)
            # Nothing moves: every image a camera sent is the same picture; the one the bridge sent is one of them.
            assert any(np.array_equal(got, drake_pixels(data, port)) for data in sent[-20:]), (camera, port)
        rgb, depth, label = (as_drake_reads(images[camera, port][-1], port, False) for port in PORTS)
        assert len(np.unique(label)) >= 5 and len(np.unique(rgb.reshape(-1, 4), axis=0)) > 100  # shapes drawn
        assert len(np.unique(depth)) > 50  # the ground and the shapes at their distances
    from pydrake.systems.sensors import CameraConfig

    drake = CameraConfig(width=WIDTH, height=HEIGHT, focal=CameraConfig.FovDegrees(y=FOV_Y_DEGREES))
    fx, fy, (cx, cy) = drake.focal_x(), drake.focal_y(), drake.principal_point()
    for (camera, _), received in infos.items():
        info = received[-1]
        assert (info.width, info.height, info.header.frame_id) == (WIDTH, HEIGHT, camera)
        assert list(info.k) == pytest.approx([fx, 0, cx, 0, fy, cy, 0, 0, 1], rel=1e-12)
        assert list(info.p) == pytest.approx([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], rel=1e-12)
        assert list(info.d) == [0.0] * 5 and info.distortion_model == "plumb_bob"


ROS_ENCODINGS = ("rgb8", "rgba8", "bgr8", "bgra8", "mono8", "mono16", "16UC1", "32FC1", "16SC1")


def test_rclpy_images_reach_drakes_image_reader(probe: RosProbe) -> None:
    from sensor_msgs.msg import Image

    url = lcm_url(24)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--lcm-url", url)
    publisher = probe.publisher("/drake_in/camera/image", "sensor_msgs/msg/Image")
    sent: dict[str, np.ndarray] = {}
    arrived: dict[str, bytes] = {}
    try:
        bridge.wait_for_line(" running (")
        for second, encoding in enumerate(ROS_ENCODINGS, start=1):
            pixels = sent[encoding] = ros_test_image(encoding)
            message = Image(height=pixels.shape[0], width=pixels.shape[1], encoding=encoding)
            message.header.frame_id, message.header.stamp.sec = "ros_camera", second
            message.step = pixels.shape[1] * pixels.shape[2] * pixels.dtype.itemsize
            message.data = pixels.tobytes()
            deadline = time.monotonic() + 60
            while encoding not in arrived and time.monotonic() < deadline:  # until discovery matched
                publisher.publish(message)
                time.sleep(0.1)
                for data in recorder.messages.get("DRAKE_RGBD_CAMERA_IMAGES_FROM_ROS", []):
                    if drake_lcmtypes.lcmt_image_array.decode(data).header.utime == second * 1_000_000:
                        arrived[encoding] = data
            assert encoding in arrived, f"no lcmt_image_array for {encoding}; bridge log:\n{bridge.lines}"
    finally:
        assert bridge.stop() == 0
        recorder.close()
    for encoding, data in arrived.items():
        assert drake_lcmtypes.lcmt_image_array.decode(data).header.frame_name == "ros_camera"
        assert_drake_reads(encoding, sent[encoding], data)


def test_drake_cameras_reach_a_foxglove_client_as_raw_images() -> None:
    """builtin:foxglove, the protocol client of tests/transports/test_foxglove.py: RawImage with
    the pixels Drake's reader reads, stamped (`time: sim`) with the sim time of an image Drake sent."""
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

    from tests.transports.test_foxglove import foxglove_port, python_client

    url = lcm_url(25)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("-c", "builtin:foxglove", "--lcm-url", url, "--set", "time=sim")
    simulation = client = None
    topics = [f"/drake/cameras/left/{port}/image" for port in PORTS]
    try:
        port = foxglove_port(bridge)
        simulation = subprocess.Popen([sys.executable, str(SCENE), url, "120"])
        client = python_client(port, *topics)  # channels are advertised with their first image
        assert client.pump(90, lambda: all(client.messages.get(topic) for topic in topics)), client.log()  # type: ignore[union-attr]
    finally:
        if client is not None:
            client.close()
        if simulation is not None:
            simulation.terminate()
            simulation.wait(timeout=30)
        assert bridge.stop() == 0
        recorder.close()
    sent = recorder.messages["DRAKE_RGBD_CAMERA_IMAGES_left"]
    sent_us = {drake_lcmtypes.lcmt_image_array.decode(data).header.utime for data in sent}
    for port, topic in zip(PORTS, topics, strict=True):
        message = RawImage.FromString(client.messages[topic][-1])
        assert (message.width, message.height, message.frame_id) == (WIDTH, HEIGHT, "left")
        assert message.encoding == {"rgb": "rgba8", "depth": "16UC1", "label": "16UC1"}[port]
        assert message.timestamp.seconds * 1_000_000 + message.timestamp.nanos // 1000 in sent_us  # sim time
        got = as_drake_reads(message, port, compressed=True)
        assert any(np.array_equal(got, drake_pixels(data, port)) for data in sent[-20:]), port
