"""The ROS 2 transport: a type this environment lacks is refused at start, saying what to install."""

from __future__ import annotations

import pytest

from viewer_bridge.errors import TransportUnavailable
from viewer_bridge.transports import TRANSPORTS
from viewer_bridge.transports.base import CDR, MessageType


def test_a_missing_interface_is_refused_at_start_naming_the_fix() -> None:
    transport_class = TRANSPORTS.get("ros")
    transport = transport_class(transport_class.Settings(node="require_probe"))
    try:
        transport.require([MessageType("geometry_msgs/msg/PoseArray", CDR)])  # installed: fine
        with pytest.raises(TransportUnavailable, match="viewer-bridge ros-interfaces install tf2_msgs"):
            transport.require([MessageType("tf2_msgs/msg/NoSuchMessage", CDR)])
        with pytest.raises(TransportUnavailable, match="ros-jazzy-made-up-msgs"):
            transport.require([MessageType("made_up_msgs/msg/Nothing", CDR)])
    finally:
        transport.close()


def test_an_lcm_types_interface_not_built_yet_holds_its_channel_and_the_rest_flows() -> None:
    """Over DDS an LCM type's ROS 2 mapping needs its interface built (the lcmros work): until it
    is, its channel's messages wait, counted per channel (`waiting_for_build`), never an error,
    while the other routes publish."""
    import drake as drake_lcmtypes

    from tests.scenes import draw_of, small_scene
    from viewer_bridge.config import BridgeConfig
    from viewer_bridge.router import Router
    from viewer_bridge.transports.base import Received

    config = BridgeConfig.model_validate(
        {"lcm": {"url": "memq://"}, "ros": {"node": "held_probe"}, "routes": [
            {"name": "bus", "source": {"transport": "lcm", "name": "(IIWA_.*)"}, "translator": "lcm_to_ros",
             "destination": {"transport": "ros", "name": "/lcm/{1:topic}"}},
            {"name": "poses", "source": {"transport": "lcm", "name": "DRAKE_VIEWER_DRAW"},
             "translator": "drake_to_pose_array", "destination": {"transport": "ros", "name": "drake/poses"}},
        ]}
    )  # fmt: skip
    router = Router(config)
    try:
        for step in range(3):
            router.feed("lcm", Received("IIWA_STATUS", drake_lcmtypes.lcmt_iiwa_status().encode()))
            router.feed("lcm", Received("DRAKE_VIEWER_DRAW", draw_of(small_scene(), step)))
        snapshot = router.snapshot()
    finally:
        router.close()
    assert snapshot["bus"]["held"] == {"IIWA_STATUS": {"waiting_for_build": 3}}
    assert snapshot["bus"]["errors"] == {} and snapshot["poses"]["errors"] == {}
    assert snapshot["poses"]["messages_out"] == 3
