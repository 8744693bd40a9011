"""A TF tree per draw and markers in link frames: roles, static links, and a real pydrake simulation
(the TFMessage encoder itself: tests/formats/ros/test_tf.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import numpy as np
import pytest

from tests.conftest import lcm_url
from tests.formats import oracle
from tests.peers import BridgeProcess, RosProbe
from tests.test_router import LcmRecorder, start_drake
from viewer_bridge.errors import EncodeError
from viewer_bridge.examples.scenes import draw_of, small_scene
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.formats.ros.messages import from_cdr
from viewer_bridge.model.scene import Box, Geometry, Link, Pose, Scene
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import Received

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)


def translate_all(translator: Any, *messages: Received) -> list[tuple[int, bytes]]:
    out = []
    for message in messages:
        translator.observe(message)
        out += translator.translate(message)
    return out


def test_roles_get_their_own_frames_and_static_links_are_sent_once() -> None:
    scene = Scene((*small_scene().links, Link("plant::robot::fixed", 1, (Geometry(Box((1, 1, 1))),))))
    load = load_from_scene(scene).encode()
    draw = draw_of(small_scene(), 1.0)  # poses base and tip; "fixed" is never drawn
    out: dict[str, list[tuple[int, bytes]]] = {}
    for suffix in ("", "_PROXIMITY"):
        tf = TRANSLATORS.get("drake_to_tf")({})
        out[suffix] = translate_all(
            tf,
            Received(f"DRAKE_VIEWER_LOAD_ROBOT{suffix}", load),
            Received(f"DRAKE_VIEWER_DRAW{suffix}", draw, 1_700_000_000_250_000),
            Received(f"DRAKE_VIEWER_DRAW{suffix}", draw, 1_700_000_000_260_000),
        )
    # Per load, /tf_static once (index 1), before the first /tf; then /tf per draw.
    assert [index for index, _ in out[""]] == [1, 0, 0]
    static = from_cdr(out[""][0][1], "tf2_msgs/msg/TFMessage").transforms
    assert [(t.header.frame_id, t.child_frame_id) for t in static] == [("world", "plant/robot/fixed")]
    first = from_cdr(out[""][1][1], "tf2_msgs/msg/TFMessage").transforms
    assert [t.child_frame_id for t in first] == ["plant/robot/base", "plant/robot/tip"]
    assert (first[0].header.stamp.sec, first[0].header.stamp.nanosec) == (1_700_000_000, 250_000_000)
    proximity = from_cdr(out["_PROXIMITY"][1][1], "tf2_msgs/msg/TFMessage").transforms
    assert [t.child_frame_id for t in proximity] == [
        "proximity/plant/robot/base",
        "proximity/plant/robot/tip",
    ]
    sim = TRANSLATORS.get("drake_to_tf")({"stamp": "sim"})
    ((_, data),) = translate_all(sim, Received("DRAKE_VIEWER_DRAW", draw_of(small_scene(), 61.25)))
    stamp = from_cdr(data, "tf2_msgs/msg/TFMessage").transforms[0].header.stamp
    assert (stamp.sec, stamp.nanosec) == (61, 250_000_000)
    # int32 sec: too early
    before_1902 = Received("DRAKE_VIEWER_DRAW", draw_of(small_scene(), -(2.0**31) - 1))
    with pytest.raises(EncodeError, match="does not fit int32 seconds"):
        sim.translate(before_1902)


def test_link_markers_are_in_link_frames_once_per_load() -> None:
    scene = Scene((Link("plant::robot::base", 1, (Geometry(Box((0.1, 0.2, 0.3)), Pose((1.0, 2.0, 3.0))),)),
                   Link("world", 0, (Geometry(Box((5, 5, 0.1))),))))  # fmt: skip
    markers = TRANSLATORS.get("drake_to_link_markers")({})
    load = Received("DRAKE_VIEWER_LOAD_ROBOT_PROXIMITY", load_from_scene(scene).encode())
    draw = Received("DRAKE_VIEWER_DRAW_PROXIMITY", draw_of(small_scene(), 1.0))
    ((_, data),) = translate_all(markers, load, draw, load)  # the draw and the re-sent load: nothing
    array = from_cdr(data, "visualization_msgs/msg/MarkerArray").markers
    assert array[0].action == 3  # DELETEALL
    base, world = array[1], array[2]
    assert (base.header.frame_id, base.frame_locked) == ("proximity/plant/robot/base", True)
    assert [base.pose.position.x, base.pose.position.y, base.pose.position.z] == [1.0, 2.0, 3.0]
    assert (world.header.frame_id, world.frame_locked) == ("world", True)


# --- end to end: pydrake -> bridge process -> rclpy /tf, /tf_static, link markers ---------------------


def compose(transform: Any, pose: Any) -> tuple[np.ndarray, np.ndarray]:
    """A TransformStamped's transform times a Marker's pose, by pydrake: (position, x y z w)."""
    t, r = transform.translation, transform.rotation
    p, q = pose.position, pose.orientation
    world = oracle.transform([t.x, t.y, t.z], [r.w, r.x, r.y, r.z]) @ oracle.transform(
        [p.x, p.y, p.z], [q.w, q.x, q.y, q.z]
    )
    quaternion = world.rotation().ToQuaternion()
    xyzw = np.array([quaternion.x(), quaternion.y(), quaternion.z(), quaternion.w()])
    return world.translation(), xyzw


@pytest.mark.slow
def test_a_drake_simulation_reaches_ros_as_a_tf_tree(tmp_path: Path) -> None:
    probe = RosProbe("tf_probe")
    url = lcm_url(11)
    tf = probe.subscribe("/tf", "tf2_msgs/msg/TFMessage", 100)
    tf_static = probe.subscribe("/tf_static", "tf2_msgs/msg/TFMessage", 100, latched=True)
    markers = probe.subscribe("/drake/illustration/link_markers", "visualization_msgs/msg/MarkerArray", 1,
                              latched=True)  # fmt: skip
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--lcm-url", url, "--stats-period", "1")
    try:
        bridge.wait_for_line(" running (")
        drake = start_drake(url, tmp_path, 2.0)
        assert drake.wait(timeout=120) == 0
        recorder.sync()  # holds Drake's last draw
        last_draw = drake_lcmtypes.lcmt_viewer_draw.decode(
            recorder.messages["DRAKE_VIEWER_DRAW_ILLUSTRATION"][-1]
        )

        def has_last_draw() -> bool:  # stamps are receive times: the positions tell the draw
            illustration = [m for m in tf if not m.transforms[0].child_frame_id.startswith("proximity/")]
            if not illustration:
                return False
            by_child = {t.child_frame_id: t.transform.translation for t in illustration[-1].transforms}
            return all(
                (t := by_child.get(name.replace("::", "/"))) is not None
                and oracle.close([t.x, t.y, t.z], position)
                for name, position in zip(last_draw.link_name, last_draw.position, strict=True)
            )

        # The last draw's TFMessage follows the simulation's end.
        assert probe.wait_for(lambda: bool(markers) and has_last_draw())
    finally:
        assert bridge.stop() == 0
        recorder.close()
        probe.close()
    load = drake_lcmtypes.lcmt_viewer_load_robot.decode(
        recorder.messages["DRAKE_VIEWER_LOAD_ROBOT_ILLUSTRATION"][0]
    )
    # The tree: the last illustration TFMessage (unprefixed frames) is the last draw, world -> link.
    illustration = [m for m in tf if not m.transforms[0].child_frame_id.startswith("proximity/")]
    transforms = {t.child_frame_id: t for t in illustration[-1].transforms}
    assert set(transforms) == {name.replace("::", "/") for name in last_draw.link_name}
    for name, position, wxyz in zip(
        last_draw.link_name, last_draw.position, last_draw.quaternion, strict=True
    ):
        found = transforms[name.replace("::", "/")]
        assert found.header.frame_id == "world"
        t, r = found.transform.translation, found.transform.rotation
        assert oracle.close([t.x, t.y, t.z], position)
        assert oracle.same_rotation([r.x, r.y, r.z, r.w], oracle.xyzw_of(wxyz))
    # Every link Drake draws is moving, welded or not: nothing is static but the world link's.
    assert tf_static == [] or all(len(m.transforms) == 0 for m in tf_static)
    # Markers in link frames, composed with those transforms, land where Drake puts each geometry.
    array = markers[-1].markers
    assert array[0].action == 3 and all(m.frame_locked for m in array[1:])
    checked = 0
    for link in load.link:
        if link.name == "world":
            continue
        row = list(last_draw.link_name).index(link.name)
        marker = next(m for m in array if m.ns == link.name.replace("::", "/") and m.id == 0)
        assert marker.header.frame_id == link.name.replace("::", "/")
        position, xyzw = compose(transforms[marker.header.frame_id].transform, marker.pose)
        expected_position, expected_xyzw = oracle.world_pose(last_draw.position[row], last_draw.quaternion[row],
                                                             link.geom[0])  # fmt: skip
        assert oracle.close(position, expected_position), link.name
        assert oracle.same_rotation(xyzw, expected_xyzw), link.name
        checked += 1
    assert checked == 16  # two model instances of eight shapes
