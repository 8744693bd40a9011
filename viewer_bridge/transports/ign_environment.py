"""The environment of an ign/gz-transport node: the `GZ_*` variables, with the `IGN_*` ones as fallbacks.

gz-transport 13 (Gazebo Harmonic and later) reads only `GZ_*`; ign-transport 11 (Fortress) only
`IGN_*`. The bridge reads both as gz-transport 12 does: the `GZ_` name first, else the `IGN_`
one, so one environment serves either generation (docs/PROTOCOLS.md section 11). An `IGN_` name
is used with a warning only when the bridge speaks to Harmonic or later, which ignore it.
Values that cannot be used (a port that is no port, a relay that is no IPv4 address) are logged
and replaced by the default, as gz-transport does.
"""

from __future__ import annotations

import ipaddress
import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass

log = logging.getLogger("viewer_bridge")

DISCOVERY_GROUP = "239.255.0.7"
MESSAGE_PORT = 10317
SERVICE_PORT = 10318


@dataclass(frozen=True)
class NodeEnvironment:
    """What the environment says of a node; None where it says nothing (the node's default)."""

    partition: str | None = None  # GZ_PARTITION
    ip: str | None = None  # GZ_IP: the interface for data and discovery
    relays: tuple[str, ...] = ()  # GZ_RELAY: unicast discovery peers beyond the multicast group
    group: str = DISCOVERY_GROUP  # GZ_DISCOVERY_MULTICAST_IP
    message_port: int = MESSAGE_PORT  # GZ_DISCOVERY_MSG_PORT
    service_port: int = SERVICE_PORT  # GZ_DISCOVERY_SRV_PORT
    topic_statistics: bool = False  # GZ_TRANSPORT_TOPIC_STATISTICS=1: wire version 110


def variable(environ: Mapping[str, str], name: str, fortress: bool = False) -> str | None:
    """`GZ_<name>`, else `IGN_<name>`; None when neither is set or both are empty.

    For a node that talks to Fortress (`fortress`: the `ignition` package) the `IGN_` name is
    that Gazebo's own and is read quietly; for Harmonic and later, which read only `GZ_`, an
    `IGN_` name is used with a warning, since the Gazebo tools beside the bridge ignore it.
    """
    value = environ.get(f"GZ_{name}")
    if value:
        return value
    value = environ.get(f"IGN_{name}")
    if value and not fortress:
        log.warning(
            "IGN_%s is Fortress's name; Harmonic and later (gz-transport 13) read only GZ_%s: using it "
            "here, but set GZ_%s for gz tools to agree (or use -c builtin:ign for Fortress)",
            name, name, name,
        )  # fmt: skip
    return value or None


def read_environment(environ: Mapping[str, str] = os.environ, fortress: bool = False) -> NodeEnvironment:
    """The node's environment; `fortress`: the bridge speaks to Fortress (ign-transport 11), whose
    `IGN_*` names are then read without a warning."""
    message_port = _port(environ, "DISCOVERY_MSG_PORT", MESSAGE_PORT, fortress)
    service_port = _port(environ, "DISCOVERY_SRV_PORT", SERVICE_PORT, fortress)
    if service_port == message_port:  # gz-transport moves the service port aside, and so do we
        service_port = message_port + 1 if message_port < 65535 else message_port - 1
        log.warning(
            "the discovery ports are the same: %d for messages, %d for services", message_port, service_port
        )
    return NodeEnvironment(
        partition=variable(environ, "PARTITION", fortress),
        ip=variable(environ, "IP", fortress),
        relays=_relays(variable(environ, "RELAY", fortress) or ""),
        group=variable(environ, "DISCOVERY_MULTICAST_IP", fortress) or DISCOVERY_GROUP,
        message_port=message_port,
        service_port=service_port,
        topic_statistics=variable(environ, "TRANSPORT_TOPIC_STATISTICS", fortress) == "1",
    )


def _port(environ: Mapping[str, str], name: str, default: int, fortress: bool) -> int:
    text = variable(environ, name, fortress)
    if text is None:
        return default
    if text.isdigit() and 0 < int(text) < 65536:
        return int(text)
    log.warning("GZ_%s=%r is not a port: using %d", name, text, default)
    return default


def _relays(text: str) -> tuple[str, ...]:
    """`GZ_RELAY`: IPv4 addresses separated by colons, as gz-transport splits it."""
    relays = []
    for part in filter(None, text.split(":")):
        try:
            relays.append(str(ipaddress.IPv4Address(part)))
        except ValueError:
            log.warning("GZ_RELAY: %r is not an IPv4 address: left out", part)
    return tuple(relays)
