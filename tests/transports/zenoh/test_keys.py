"""rmw_zenoh's names and stamps (viewer_bridge.transports.zenoh.keys) against examples written by hand
from rmw_zenoh's design document and sources (docs/PROTOCOLS.md section 10), and the session's
configuration as rmw_zenoh composes it. Pure functions: no session, no router."""

from __future__ import annotations

import contextlib
import struct
from typing import Any

import pytest
import xxhash
from hypothesis import given
from hypothesis import strategies as st

from viewer_bridge.errors import DecodeError
from viewer_bridge.transports.zenoh import keys
from viewer_bridge.transports.zenoh.session import overrides_from_env, session_config

POSE_ARRAY_HASH = "RIHS01_af0cc36d190e104d546d168d6b39df04fa4b4ccecf59cb4c9ed328d3d5004aa0"


def test_type_hashes_are_rclpys() -> None:
    """rosbags computes them from the definitions; rclpy's generated code carries them: they agree."""
    import rclpy
    from rclpy.node import Node

    from viewer_bridge.transports.ros2 import message_class

    rclpy.init()
    try:
        node = Node("zenoh_hash_probe")
        for index, name in enumerate(
            ("geometry_msgs/msg/PoseArray", "tf2_msgs/msg/TFMessage", "visualization_msgs/msg/MarkerArray")
        ):
            node.create_publisher(message_class(name), f"/hash_probe_{index}", 1)
            (info,) = node.get_publishers_info_by_topic(f"/hash_probe_{index}")
            assert keys.topic_type(name).hash == str(info.topic_type_hash), name
        node.destroy_node()
    finally:
        rclpy.shutdown()


def test_data_key() -> None:
    pose_array = keys.topic_type("geometry_msgs/msg/PoseArray")
    assert pose_array == keys.TopicType(
        "geometry_msgs/msg/PoseArray", "geometry_msgs::msg::dds_::PoseArray_", POSE_ARRAY_HASH
    )
    key = keys.data_key(3, "/drake/illustration/poses", pose_array)
    assert key == f"3/drake/illustration/poses/geometry_msgs::msg::dds_::PoseArray_/{POSE_ARRAY_HASH}"
    assert keys.parse_data_key(key) == keys.DataKey(
        3, "/drake/illustration/poses", "geometry_msgs::msg::dds_::PoseArray_", POSE_ARRAY_HASH
    )
    with pytest.raises(KeyError):
        keys.topic_type("made_up_msgs/msg/Nothing")


@pytest.mark.parametrize(
    ("key", "field"),
    [
        ("0/tf", "key"),
        ("x/tf/tf2_msgs::msg::dds_::TFMessage_/" + POSE_ARRAY_HASH, "domain"),
        ("0//tf2_msgs::msg::dds_::TFMessage_/" + POSE_ARRAY_HASH, "topic"),
        ("0/tf/tf2_msgs/msg/TFMessage/" + POSE_ARRAY_HASH, "type"),
        ("0/tf/tf2_msgs::msg::dds_::TFMessage_/RIHS01_xyz", "type_hash"),
    ],
)
def test_a_key_that_does_not_parse_names_its_part(key: str, field: str) -> None:
    with pytest.raises(DecodeError) as raised:
        keys.parse_data_key(key)
    assert raised.value.field == field


NODE = keys.NodeName("viewer_bridge", "/sim1", "/")


def test_tokens_are_rmw_zenohs() -> None:
    node = keys.Token(0, "aa11", 0, 0, keys.NODE, NODE)
    assert node.key() == "@ros2_lv/0/aa11/0/0/NN/%/%sim1/viewer_bridge"
    pose_array = keys.topic_type("geometry_msgs/msg/PoseArray")
    topic = keys.TopicEntity(
        "/sim1/drake/poses", pose_array.dds_name, pose_array.hash, keys.TokenQos(depth=7)
    )
    publisher = keys.Token(0, "aa11", 0, 4, keys.PUBLISHER, NODE, topic)
    assert publisher.key() == (
        "@ros2_lv/0/aa11/0/4/MP/%/%sim1/viewer_bridge/%sim1%drake%poses/"
        f"geometry_msgs::msg::dds_::PoseArray_/{POSE_ARRAY_HASH}/::,7:,:,:,,"
    )
    assert keys.parse_token(publisher.key()) == publisher
    assert keys.parse_token(node.key()) == node
    # The GID: XXH3-128 of the token's key, low 64 bits first, little-endian.
    digest = xxhash.xxh3_128_intdigest(publisher.key().encode())
    assert keys.gid(publisher.key()) == struct.pack("<QQ", digest & (2**64 - 1), digest >> 64)


@pytest.mark.parametrize(
    ("qos", "text"),
    [
        (keys.TokenQos(), "::,:,:,:,,"),  # rmw_zenoh's defaults: reliable, volatile, keep last 42
        (keys.TokenQos(depth=10), "::,10:,:,:,,"),
        (keys.TokenQos(transient_local=True, depth=1), ":1:,1:,:,:,,"),
        (keys.TokenQos(reliable=False, depth=100), "2::,100:,:,:,,"),
        (keys.TokenQos(keep_all=True), "::2,:,:,:,,"),
    ],
)
def test_qos_part(qos: keys.TokenQos, text: str) -> None:
    assert keys.qos_part(qos) == text
    assert keys.parse_qos_part(text) == qos


@pytest.mark.parametrize(
    ("key", "field"),
    [
        ("@ros2_lv/0/aa/0/0/NN/%/%", "key"),  # 8 parts
        ("@other/0/aa/0/0/NN/%/%/n", "admin_space"),
        ("@ros2_lv/zero/aa/0/0/NN/%/%/n", "domain"),
        ("@ros2_lv/0/aa/x/0/NN/%/%/n", "node_id"),
        ("@ros2_lv/0/aa/0/0/XX/%/%/n", "kind"),
        ("@ros2_lv/0/aa/0/0/MP/%/%/n", "key"),  # a publisher without its topic
        ("@ros2_lv/0/aa/0/1/MP/%/%/n/%t/T/H/9::,:,:,:,,", "qos.reliability"),
        ("@ros2_lv/0/aa/0/1/MS/%/%/n/%t/T/H/::,x:,:,:,,", "qos.depth"),
        ("@ros2_lv/0/aa/0/1/MS/%/%/n/%t/T/H/::", "qos.qos"),
        ("@ros2_lv/0/aa/0/1/MS/%/%/n/%t/T/H/::,,1:,:,:,,", "qos.depth"),  # bench/fuzz.py's find: int(",1")
        ("@ros2_lv/0/aa/0/1/MS/%/%/n/%t/T/H/::,:,:,:,", "qos.liveliness"),
    ],
)
def test_junk_tokens_are_decode_errors_naming_the_part(key: str, field: str) -> None:
    with pytest.raises(DecodeError) as raised:
        keys.parse_token(key)
    assert raised.value.field == field


def test_attachment() -> None:
    gid = bytes(range(16))
    data = keys.attachment(5, 1_700_000_000_123_456_789, gid)
    assert len(data) == 33
    assert data == struct.pack("<qq", 5, 1_700_000_000_123_456_789) + b"\x10" + gid
    assert keys.parse_attachment(data) == keys.Attachment(5, 1_700_000_000_123_456_789, gid)
    for bad in (b"", data[:32], data + b"\0", data[:16] + b"\x0f" + data[17:]):
        with pytest.raises(DecodeError):
            keys.parse_attachment(bad)


@given(st.text(max_size=200))
def test_parsers_refuse_any_text_with_a_decode_error_only(text: str) -> None:
    for parse in (keys.parse_data_key, keys.parse_token, keys.parse_qos_part):
        with contextlib.suppress(DecodeError):
            parse(text)


@given(st.binary(max_size=64))
def test_attachment_parser_refuses_any_bytes_with_a_decode_error_only(data: bytes) -> None:
    with contextlib.suppress(DecodeError):
        keys.parse_attachment(data)


# --- the session's configuration --------------------------------------------------------------------


def _config(file: str | None = None, options: dict[str, Any] | None = None, **environ: str) -> Any:
    settings = {"mode": None, "connect": None, "listen": None}
    return session_config(file, settings, options or {}, environ)


def test_without_a_file_the_bridge_is_a_client_of_the_local_router_listening_nowhere() -> None:
    file, pairs = _config()
    assert file is None
    assert dict(pairs) == {
        "mode": '"client"',
        "connect/endpoints": '["tcp/localhost:7447"]',
        "listen/endpoints": "[]",
        "scouting/multicast/enabled": "false",
        "timestamping/enabled": "true",
    }


def test_a_router_dials_no_router_and_listens_on_this_machine_where_its_clients_connect() -> None:
    from viewer_bridge.transports.zenoh.session import described, make_config

    for environ, settings in [
        ({}, {"mode": "router", "connect": None, "listen": None}),
        ({"ZENOH_CONFIG_OVERRIDE": "mode='router'"}, {"mode": None, "connect": None, "listen": None}),
    ]:
        file, pairs = session_config(None, settings, {}, environ)
        assert described(make_config(file, pairs)) == ("router", [], ["tcp/127.0.0.1:7447"])
    # what it is told still wins; a peer dials the local router as a client does
    file, pairs = session_config(
        None, {"mode": "router", "connect": ["tcp/10.0.0.1:7447"], "listen": None}, {}, {}
    )
    assert described(make_config(file, pairs)) == ("router", ["tcp/10.0.0.1:7447"], ["tcp/127.0.0.1:7447"])
    file, pairs = session_config(None, {"mode": "peer", "connect": None, "listen": None}, {}, {})
    assert described(make_config(file, pairs)) == ("peer", ["tcp/localhost:7447"], [])


def test_a_config_file_and_overrides_as_rmw_zenoh_reads_them() -> None:
    override = 'connect/endpoints=["tcp/10.0.0.1:7447"];mode="peer";no_equals;transport/link/tls/x=a=b'
    file, pairs = _config(ZENOH_SESSION_CONFIG_URI="/etc/zenoh.json5", ZENOH_CONFIG_OVERRIDE=override)
    assert file == "/etc/zenoh.json5"
    assert pairs == [
        ("connect/endpoints", '["tcp/10.0.0.1:7447"]'),
        ("mode", '"peer"'),
        ("transport/link/tls/x", "a=b"),
        ("timestamping/enabled", "true"),
    ]
    # The transport's own file and settings win over the environment's; its `config` keys come last.
    file, pairs = session_config(
        "mine.json5",
        {"mode": "client", "connect": ["tls/router:7447"], "listen": None},
        {"transport/link/tls/root_ca_certificate": "ca.pem"},
        {"ZENOH_SESSION_CONFIG_URI": "/etc/zenoh.json5", "ZENOH_CONFIG_OVERRIDE": 'mode="peer"'},
    )
    assert file == "mine.json5"
    assert pairs == [
        ("mode", '"peer"'),
        ("mode", '"client"'),
        ("connect/endpoints", '["tls/router:7447"]'),
        ("transport/link/tls/root_ca_certificate", '"ca.pem"'),
        ("timestamping/enabled", "true"),
    ]
    assert overrides_from_env("") == []


def test_a_key_zenoh_refuses_is_refused_when_the_transport_is_made() -> None:
    from viewer_bridge.transports.zenoh.transport import ZenohSettings, ZenohTransport

    with pytest.raises(ValueError, match="no/such/key"):
        ZenohTransport(ZenohSettings(config={"no/such/key": 1}))
    with pytest.raises(ValueError, match="Zenoh config file"):
        ZenohTransport(ZenohSettings(config_file="/no/such/zenoh.json5"))
