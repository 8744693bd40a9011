"""The ROS 2 transport: a type this environment lacks is refused at start, saying what to install."""

from __future__ import annotations

import pytest

from viewer_bridge.errors import TransportUnavailable
from viewer_bridge.transports.base import CDR, MessageType
from viewer_bridge.transports.registry import TRANSPORTS

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)


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


def test_drakes_driver_messages_reach_an_rclpy_subscriber_of_the_built_interfaces() -> None:
    """A pydrake diagram publishes `lcmt_iiwa_status` and `lcmt_robot_plan` (LcmPublisherSystems)
    on the bus; the default config's lazy LCM-bus route carries them to /lcm/<channel> as
    drake_lcm_msgs (built by the project's setup), and an rclpy subscriber that imports those
    classes gets every field equal to Drake's own decode of the bytes sent.

    The subscriber comes once the driver's messages are on the bus (the lazy route idle): as when
    DDS discovery is late on a loaded machine, it matches mid-stream and still gets its share,
    since the driver publishes until it has (a run of fixed length left it 15 of 300)."""
    import drake as drake_lcmtypes

    from tests.conftest import lcm_url
    from tests.drake_robot_status import PLAN_CHANNEL, STATUS_CHANNEL, drive_until
    from tests.peers import BridgeProcess, RosProbe
    from tests.test_router import LcmRecorder
    from tests.translators.test_lcm_generic import assert_same

    url = lcm_url(61)
    recorder = LcmRecorder(url)
    bridge = BridgeProcess("--lcm-url", url)
    probe = RosProbe("lcm_bus_subscriber")
    topics = {
        STATUS_CHANNEL: "drake_lcm_msgs/msg/LcmtIiwaStatus",
        PLAN_CHANNEL: "drake_lcm_msgs/msg/LcmtRobotPlan",
    }

    def arrived() -> bool:
        if not probe.received:
            if not recorder.messages.get(STATUS_CHANNEL):
                return False  # the driver has not published yet
            for channel, typename in topics.items():
                probe.subscribe(f"/lcm/{channel}", typename, depth=1000)
        return (
            len(probe.received[f"/lcm/{STATUS_CHANNEL}"]) >= 30
            and len(probe.received[f"/lcm/{PLAN_CHANNEL}"]) >= 3
        )

    try:
        bridge.wait_for_line(" running (")
        assert drive_until(url, arrived), (
            {topic: len(messages) for topic, messages in probe.received.items()},
            bridge.lines[-10:],
        )
        recorder.sync()  # holds every message the driver sent
    finally:
        probe.close()
        assert bridge.stop() == 0
        recorder.close()
    for channel, lcm_class in ((STATUS_CHANNEL, drake_lcmtypes.lcmt_iiwa_status),
                               (PLAN_CHANNEL, drake_lcmtypes.lcmt_robot_plan)):  # fmt: skip
        received = probe.received[f"/lcm/{channel}"]
        assert received, channel
        sent = {lcm_class.decode(data).utime: data for data in recorder.messages[channel]}
        for message in received:
            assert_same(lcm_class.decode(sent[message.utime]), message)
