"""The node's environment: GZ_* names first, IGN_* as fallbacks with a warning (as gz-transport 12)."""

from __future__ import annotations

import logging

import pytest

from viewer_bridge.transports.ign import IgnNode
from viewer_bridge.transports.ign_environment import (
    DISCOVERY_GROUP,
    MESSAGE_PORT,
    SERVICE_PORT,
    NodeEnvironment,
    read_environment,
)


def test_nothing_set_is_the_defaults(caplog: pytest.LogCaptureFixture) -> None:
    assert read_environment({}) == NodeEnvironment(
        None, None, (), DISCOVERY_GROUP, MESSAGE_PORT, SERVICE_PORT, False
    )
    assert not caplog.records


def test_every_gz_name_is_read_without_a_warning(caplog: pytest.LogCaptureFixture) -> None:
    environ = {
        "GZ_PARTITION": "sim", "GZ_IP": "127.0.0.1", "GZ_RELAY": "10.0.0.2:10.0.0.3",
        "GZ_DISCOVERY_MULTICAST_IP": "239.255.0.8", "GZ_DISCOVERY_MSG_PORT": "11317",
        "GZ_DISCOVERY_SRV_PORT": "11318", "GZ_TRANSPORT_TOPIC_STATISTICS": "1",
    }  # fmt: skip
    assert read_environment(environ) == NodeEnvironment(
        "sim", "127.0.0.1", ("10.0.0.2", "10.0.0.3"), "239.255.0.8", 11317, 11318, True
    )
    assert not caplog.records


def test_an_ign_name_alone_is_used_with_a_warning(caplog: pytest.LogCaptureFixture) -> None:
    environ = {
        "IGN_PARTITION": "fortress", "IGN_IP": "127.0.0.1", "IGN_RELAY": "10.0.0.2",
        "IGN_DISCOVERY_MULTICAST_IP": "239.255.0.9", "IGN_DISCOVERY_MSG_PORT": "12317",
        "IGN_DISCOVERY_SRV_PORT": "12318",
    }  # fmt: skip
    with caplog.at_level(logging.WARNING, "viewer_bridge"):
        environment = read_environment(environ)
    assert environment == NodeEnvironment("fortress", "127.0.0.1", ("10.0.0.2",), "239.255.0.9", 12317, 12318)
    warned = sorted(record.getMessage().split()[0] for record in caplog.records)
    assert warned == sorted(environ), warned
    assert "Harmonic and later (gz-transport 13) read only GZ_PARTITION" in caplog.text


def test_an_ign_name_is_read_quietly_for_fortress(caplog: pytest.LogCaptureFixture) -> None:
    """`-c builtin:ign` (Fortress) reads IGN_PARTITION, as the Gazebo guide says to set, without a
    warning: Fortress's tools read that name too."""
    with caplog.at_level(logging.WARNING, "viewer_bridge"):
        environment = read_environment({"IGN_PARTITION": "fortress", "IGN_IP": "127.0.0.1"}, fortress=True)
    assert (environment.partition, environment.ip) == ("fortress", "127.0.0.1")
    assert not caplog.records


def test_the_gz_name_wins_and_an_empty_one_counts_as_unset(caplog: pytest.LogCaptureFixture) -> None:
    environ = {"GZ_PARTITION": "harmonic", "IGN_PARTITION": "fortress", "GZ_IP": "", "IGN_IP": "127.0.0.2"}
    with caplog.at_level(logging.WARNING, "viewer_bridge"):
        environment = read_environment(environ)
    assert (environment.partition, environment.ip) == ("harmonic", "127.0.0.2")
    assert [record.getMessage().split()[0] for record in caplog.records] == ["IGN_IP"]


@pytest.mark.parametrize("value", ["0", "65536", "-1", "port", "10317.5"])
def test_a_port_that_is_no_port_is_the_default(value: str, caplog: pytest.LogCaptureFixture) -> None:
    environment = read_environment({"GZ_DISCOVERY_MSG_PORT": value})
    assert environment.message_port == MESSAGE_PORT
    assert f"GZ_DISCOVERY_MSG_PORT={value!r} is not a port" in caplog.text


def test_equal_ports_move_the_service_port_aside(caplog: pytest.LogCaptureFixture) -> None:
    environment = read_environment({"GZ_DISCOVERY_MSG_PORT": "11000", "GZ_DISCOVERY_SRV_PORT": "11000"})
    assert (environment.message_port, environment.service_port) == (11000, 11001)
    top = read_environment({"GZ_DISCOVERY_MSG_PORT": "65535", "GZ_DISCOVERY_SRV_PORT": "65535"})
    assert (top.message_port, top.service_port) == (65535, 65534)
    assert "the discovery ports are the same" in caplog.text


def test_relays_that_are_no_ipv4_address_are_left_out(caplog: pytest.LogCaptureFixture) -> None:
    environment = read_environment({"GZ_RELAY": "10.0.0.2::host.example:300.1.1.1:10.0.0.4"})
    assert environment.relays == ("10.0.0.2", "10.0.0.4")
    assert "'host.example' is not an IPv4 address" in caplog.text and "'300.1.1.1'" in caplog.text


def test_topic_statistics_only_for_1() -> None:
    assert not read_environment({"GZ_TRANSPORT_TOPIC_STATISTICS": "0"}).topic_statistics
    assert not read_environment({"GZ_TRANSPORT_TOPIC_STATISTICS": "yes"}).topic_statistics
    assert read_environment({"IGN_TRANSPORT_TOPIC_STATISTICS": "1"}).topic_statistics


def test_a_node_takes_partition_and_ip_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("IGN_PARTITION", raising=False)
    monkeypatch.setenv("GZ_PARTITION", "from_gz_partition")
    monkeypatch.setenv("GZ_IP", "127.0.0.1")
    node = IgnNode()
    try:
        assert node.partition == "from_gz_partition" and node.address.startswith("tcp://127.0.0.1:")
        assert node.full_name("drake/pose_v") == "@/from_gz_partition@/drake/pose_v"
    finally:
        node.close()
    given = IgnNode("given", environment=NodeEnvironment(partition="ignored", ip="127.0.0.1"))
    try:
        assert given.partition == "given"  # the transport's setting beats the environment
    finally:
        given.close()
