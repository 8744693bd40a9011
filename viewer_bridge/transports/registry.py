"""`TRANSPORTS`: the registry a config's `transport:` words are looked up in. A plugin adds a
transport with an entry point in the group `viewer_bridge.transports` naming a `Transport`
subclass (see `viewer_bridge.transports.base`).
"""

from __future__ import annotations

from viewer_bridge.transports.base import Transport
from viewer_bridge.util.registry import Registry

TRANSPORTS: Registry[Transport] = Registry(
    "transport",
    "viewer_bridge.transports",
    {
        "lcm": "viewer_bridge.transports.lcm:LcmTransport",
        "ros": "viewer_bridge.transports.ros2:RosTransport",
        "ign": "viewer_bridge.transports.ign:IgnTransport",
        "foxglove": "viewer_bridge.transports.foxglove:FoxgloveTransport",
        "mcap": "viewer_bridge.transports.mcap:McapTransport",
        "zenoh": "viewer_bridge.transports.zenoh.transport:ZenohTransport",
        "rerun": "viewer_bridge.transports.rerun:RerunTransport",
    },
    Transport,
)
