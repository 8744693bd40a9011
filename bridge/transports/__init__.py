"""Transports: bytes in and out of LCM, ROS 2, ign-transport, Foxglove, MCAP files, Zenoh, and plugins'.

`TRANSPORTS` is the registry a config's `transport:` words are looked up in. A plugin adds a
transport with an entry point in the group `viewer_bridge.transports` naming a `Transport`
subclass (see `bridge.transports.base`).
"""

from __future__ import annotations

from bridge.registry import Registry
from bridge.transports.base import Transport

TRANSPORTS: Registry[Transport] = Registry(
    "transport",
    "viewer_bridge.transports",
    {
        "lcm": "bridge.transports.lcm:LcmTransport",
        "ros": "bridge.transports.ros2:RosTransport",
        "ign": "bridge.transports.ign:IgnTransport",
        "foxglove": "bridge.transports.foxglove:FoxgloveTransport",
        "mcap": "bridge.transports.mcap:McapTransport",
        "zenoh": "bridge.transports.zenoh.transport:ZenohTransport",
    },
    Transport,
)

__all__ = ["TRANSPORTS", "Transport"]
