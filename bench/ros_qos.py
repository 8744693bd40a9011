"""Benchmark: what following the publishers' QoS costs per message a ROS 2 route receives.

Run: .venv/bin/python bench/ros_qos.py [--quick]

A subscription that follows its publishers (`viewer_bridge.transports.ros2.TopicSubscription`)
matches them once a second per topic, off the message path; per message it adds one check
(is a switch under way?) and the writer's timestamp read from rclpy's message info. During a
switch (a few seconds after publishers change) it also keeps each message's key, so that what
two overlapping subscriptions both deliver is passed on once: a row measures that too. Each row
times the bridge's rclpy message callback (a 7-joint JointState's CDR, the message info rclpy
passes, one route delivered to) against the callback as it was before QoS following, in
alternating rounds of the same run.
"""

from __future__ import annotations

import time
from typing import Any

from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import paired, print_measures

from viewer_bridge.transports.base import DEPTH, DURABILITY, RELIABILITY, MessageType, Qos, Received
from viewer_bridge.transports.ros2 import Switch, TopicSubscription

JOINT_STATE = MessageType("sensor_msgs/msg/JointState", "cdr")
ADDED_US_GOAL = 1.0  # against a floor of about 15 us per message for the whole of a minimal relay


def joint_state_cdr() -> bytes:
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    message = JointState(name=[f"j{i}" for i in range(7)], position=[0.1] * 7, velocity=[0.0] * 7)
    return bytes(serialize_message(message))


def callback(switching: bool) -> Any:
    """The bridge's message callback of a subscription (no rclpy node: it is never subscribed),
    during a switch or not."""
    delivered: list[Received] = []
    follow = frozenset({RELIABILITY, DURABILITY, DEPTH})
    subscription = TopicSubscription(
        None, "/joints", JOINT_STATE, Qos(follow=follow), [delivered.append], 100
    )  # type: ignore[arg-type]
    if switching:
        subscription._switch = Switch((0, 1), time.monotonic() + 1e9)
    return subscription.message_callback(history=False), delivered


def before(data: bytes, delivers: list[Any]) -> None:
    """The callback before QoS following: the raw bytes to every route, stamped on receipt."""
    message = Received("/joints", bytes(data), message_type=JOINT_STATE)
    for each in delivers:
        each(message)


def measures(size: Size = Size.FULL) -> list[Measure]:
    data = joint_state_cdr()
    rows = []
    stamp = time.time_ns()
    sink: list[Received] = []

    def baseline() -> None:
        before(data, [sink.append])
        sink.clear()

    for switching, which, goal_us in ((False, "following its publishers", ADDED_US_GOAL),
                                      (True, "during a switch (keys kept)", None)):  # fmt: skip
        on_message, delivered = callback(switching)
        numbers = iter(range(1, 1 << 62))

        def ours(call: Any = on_message, kept: list[Received] = delivered, sequence: Any = numbers) -> None:
            number = next(sequence)
            call(data, {"source_timestamp": stamp + number, "publication_sequence_number": number})
            kept.clear()

        ours_s, base_s = paired(ours, baseline, size)
        added_us = (ours_s - base_s) * 1e6
        goal = "reported" if goal_us is None else f"adds <= {goal_us:g} us"
        met = None if goal_us is None else added_us <= goal_us
        rows.append(Measure(f"ROS 2 message callback, {which}, vs the callback before", ours_s * 1e6,
                            base_s * 1e6, "us", goal, met))  # fmt: skip
    return rows


if __name__ == "__main__":
    import sys

    print_measures(measures(Size.QUICK if "--quick" in sys.argv else Size.FULL))
