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
