"""The Zenoh transport: ROS 2 in rmw_zenoh's wire format, and raw LCM channels across networks.

`keys` (rmw_zenoh's data keys, liveliness tokens and attachments, as pure functions), `session`
(the Zenoh session's configuration, and opening it while a router may be down), `entities`
(publishers, subscriptions and the token graph on that session), `transport` (the `Transport`).
Only `keys` and `transport` import without eclipse-zenoh installed.
"""
