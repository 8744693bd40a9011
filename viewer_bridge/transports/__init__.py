"""Transports: bytes in and out of LCM, ROS 2, ign-transport, Foxglove, MCAP files, Zenoh, Rerun, and plugins'.

`base` says what a transport is (`Transport`, its publishers and subscriptions); `registry` holds
`TRANSPORTS`, the registry a config's `transport:` words are looked up in; then one module (or
folder, `zenoh`) per transport.
"""
