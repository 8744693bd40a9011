"""Discovery without sockets: what a node answers, what it connects to, what it counts.

The datagrams are built with our schema, laid out as gz-transport 13.5's `Discovery::SendMsg`
and `MessagePublisher::FillDiscovery` write them (docs/PROTOCOLS.md section 11).
"""

from __future__ import annotations

import struct
from collections import Counter
from typing import Any

import pytest

from viewer_bridge.formats.ign.schema import MESSAGES
from viewer_bridge.transports.ign_discovery import (
    ANY_TYPE,
    SILENCE_S,
    STATISTICS_VERSION,
    WIRE_VERSION,
    Discovery,
    Record,
    datagram,
)
from viewer_bridge.transports.ign_environment import (
    DISCOVERY_GROUP,
    MESSAGE_PORT,
    SERVICE_PORT,
    NodeEnvironment,
)

ADDRESS = "tcp://127.0.0.1:40000"
PEER = "tcp://127.0.0.1:40001"
TOPIC = "@/test@/drake_in/pose_v"
GROUP = (DISCOVERY_GROUP, MESSAGE_PORT)


class Peer:
    """A discovery whose datagrams, connections and reports are recorded, never sent or dialled."""

    def __init__(self, environment: NodeEnvironment | None = None, connect_error: str | None = None) -> None:
        self.sent: list[tuple[Any, tuple[str, int]]] = []
        self.connected: list[str] = []
        self.reported: Counter[str] = Counter()
        self.connect_error = connect_error
        self.discovery = Discovery(
            environment or NodeEnvironment(), ADDRESS, self._send, self._connect, self._report
        )

    def _send(self, data: bytes, destination: tuple[str, int]) -> None:
        assert struct.unpack_from("<H", data)[0] == len(data) - 2
        self.sent.append((Record.FromString(data[2:]), destination))

    def _connect(self, address: str) -> None:
        if self.connect_error:
            raise OSError(self.connect_error)
        self.connected.append(address)

    def _report(self, kind: str, text: str) -> None:
        self.reported[kind] += 1

    def receive(self, message: Any, sender: str = "127.0.0.1", now: float = 0.0) -> list[Any]:
        """Hand `message` to the discovery; what it sent in answer."""
        before = len(self.sent)
        self.discovery.on_datagram(datagram(message), sender, now)
        return [sent for sent, _ in self.sent[before:]]


def record(kind: int, version: int = WIRE_VERSION, process: str = "peer-process") -> Any:
    return Record(version=version, process_uuid=process, type=kind)


def advertise(msg_type: str, address: str = PEER, version: int = WIRE_VERSION, topic: str = TOPIC) -> Any:
    message = record(Record.ADVERTISE, version)
    publisher = message.pub
    publisher.topic, publisher.address = topic, address
    publisher.process_uuid, publisher.node_uuid = "peer-process", "peer-node"
    publisher.scope = Record.Publisher.ALL
    publisher.msg_pub.msg_type = msg_type
    return message


def test_subscribers_req_gets_a_subscribers_rep_per_subscription() -> None:
    """What `gz topic -l` / `-i` list: gz-transport 13 asks with type 8, reads type 9."""
    peer = Peer()
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    peer.discovery.subscribe("@/test@/other", "ignition.msgs.Model")
    peer.discovery.advertise("@/test@/drake/pose_v", "gz.msgs.Pose_V")  # a publisher: not in the answer
    answers = peer.receive(record(Record.SUBSCRIBERS_REQ))
    assert [answer.type for answer in answers] == [Record.SUBSCRIBERS_REP] * 2
    first = answers[0]
    assert (first.version, first.process_uuid) == (WIRE_VERSION, peer.discovery.process_uuid)
    pub = first.pub
    assert (pub.topic, pub.address, pub.process_uuid, pub.node_uuid, pub.scope) == (
        TOPIC, ADDRESS, peer.discovery.process_uuid, peer.discovery.node_uuid, Record.Publisher.ALL,
    )  # fmt: skip
    assert (pub.msg_pub.ctrl, pub.msg_pub.msg_type) == ("", "gz.msgs.Pose_V")
    assert (answers[1].pub.topic, answers[1].pub.msg_pub.msg_type) == ("@/test@/other", "ignition.msgs.Model")
    assert not peer.reported
    assert not Peer().receive(record(Record.SUBSCRIBERS_REQ))  # no subscription: nothing to say


@pytest.mark.parametrize("kind", [0, 10, 11, 1000])
def test_an_unknown_message_type_is_counted_and_skipped(kind: int) -> None:
    peer = Peer()
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    assert not peer.receive(record(kind))
    assert peer.reported == {"discovery_type": 1}
    assert peer.receive(advertise("gz.msgs.Pose_V"))  # and the node goes on


@pytest.mark.parametrize(
    "kind", [Record.HEARTBEAT, Record.NEW_CONNECTION, Record.END_CONNECTION, Record.SUBSCRIBERS_REP]
)
def test_known_types_with_nothing_to_answer_are_no_errors(kind: int) -> None:
    peer = Peer()
    assert not peer.receive(record(kind))
    assert not peer.reported


@pytest.mark.parametrize("version", [WIRE_VERSION, STATISTICS_VERSION])
@pytest.mark.parametrize("msg_type", ["gz.msgs.Pose_V", "ignition.msgs.Pose_V"])
def test_a_publisher_of_either_spelling_and_wire_version_is_connected(msg_type: str, version: int) -> None:
    peer = Peer()
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    (answer,) = peer.receive(advertise(msg_type, version=version))
    assert peer.connected == [PEER] and not peer.reported
    assert answer.type == Record.NEW_CONNECTION and answer.pub.msg_pub.ctrl == "peer-process"
    assert (answer.pub.topic, answer.pub.address, answer.pub.msg_pub.msg_type) == (TOPIC, PEER, msg_type)
    assert not peer.receive(advertise(msg_type, version=version))  # the same publisher again: nothing new
    assert peer.connected == [PEER]


def test_another_message_type_is_a_type_mismatch() -> None:
    peer = Peer()
    peer.discovery.subscribe(TOPIC, "ignition.msgs.Pose_V")
    assert not peer.receive(advertise("gz.msgs.Model_V"))
    assert not peer.receive(advertise("my.msgs.Pose_V"))
    assert peer.reported == {"type_mismatch": 2} and not peer.connected
    anything = Peer()
    anything.discovery.subscribe(TOPIC, ANY_TYPE)
    assert anything.receive(advertise("my.msgs.Pose_V")) and anything.connected == [PEER]


def test_with_topic_statistics_the_node_speaks_version_110() -> None:
    peer = Peer(NodeEnvironment(topic_statistics=True))
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    assert [sent.version for sent, _ in peer.sent] == [STATISTICS_VERSION]
    assert Peer().discovery.header(Record.HEARTBEAT).version == WIRE_VERSION


UNUSABLE = [({"version": version}, "discovery_version") for version in (0, 9, 11, 100, 111, 2**32 - 1)] + [
    ({"address": address}, "advertise_address")
    for address in ("garbage", "tcp://", "tcp://127.0.0.1", "tcp://127.0.0.1:99999", "inproc://x",
                    "tcp://127.0.0.1:0", "tcp://a b:5", "ipc:///tmp/x")
]  # fmt: skip


@pytest.mark.parametrize(("field", "kind"), UNUSABLE)
def test_another_wire_version_or_an_address_that_is_no_tcp_endpoint_is_counted_not_dialled(
    field: dict[str, Any], kind: str
) -> None:
    peer = Peer()
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    assert not peer.receive(advertise("gz.msgs.Pose_V", **field))
    assert peer.reported == {kind: 1} and not peer.connected


def test_a_refused_connection_is_counted_and_tried_again_later() -> None:
    peer = Peer(connect_error="no")
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    assert not peer.receive(advertise("gz.msgs.Pose_V"))
    peer.connect_error = None
    assert peer.receive(advertise("gz.msgs.Pose_V")) and peer.connected == [PEER]
    assert peer.reported == {"advertise_address": 1}


def test_malformed_datagrams_are_counted() -> None:
    peer = Peer()
    good = datagram(record(Record.HEARTBEAT))
    for data, kind in [(b"", "discovery_length"), (b"\x05", "discovery_length"), (good + b"x", "discovery_length"),
                       (struct.pack("<H", 3) + b"\xff\xff\xff", "discovery_parse")]:  # fmt: skip
        peer.discovery.on_datagram(data, "127.0.0.1", 0.0)
        assert peer.reported[kind] > 0, kind
    assert sum(peer.reported.values()) == 4


def test_subscribe_answered_with_advertise_and_unadvertise_forgets() -> None:
    peer = Peer()
    peer.discovery.advertise("@/test@/drake/pose_v", "gz.msgs.Pose_V")
    ask = record(Record.SUBSCRIBE)
    ask.sub.topic = "@/test@/drake/pose_v"
    (answer,) = peer.receive(ask)
    assert answer.type == Record.ADVERTISE and answer.pub.msg_pub.msg_type == "gz.msgs.Pose_V"
    ask.sub.topic = "@/test@/nothing"
    assert not peer.receive(ask)
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    peer.receive(advertise("gz.msgs.Pose_V"))
    gone = advertise("gz.msgs.Pose_V")
    gone.type = Record.UNADVERTISE
    peer.receive(gone)
    assert not peer.discovery.remotes


def test_the_heartbeat_subscribes_until_answered_and_forgets_the_silent() -> None:
    peer = Peer()
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    peer.discovery.beat(0.0)
    kinds = [(sent.type, port) for sent, (_, port) in peer.sent]
    assert (Record.HEARTBEAT, MESSAGE_PORT) in kinds and (Record.HEARTBEAT, SERVICE_PORT) in kinds
    assert kinds.count((Record.SUBSCRIBE, MESSAGE_PORT)) == 2  # at subscribe, and again
    peer.receive(advertise("gz.msgs.Pose_V"), now=1.0)
    peer.sent.clear()
    peer.discovery.beat(2.0)
    assert Record.SUBSCRIBE not in [sent.type for sent, _ in peer.sent] and peer.discovery.remotes
    peer.discovery.beat(1.0 + SILENCE_S + 0.1)
    assert not peer.discovery.remotes


def test_goodbye() -> None:
    peer = Peer()
    peer.discovery.advertise("@/test@/drake/pose_v", "gz.msgs.Pose_V")
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    peer.receive(advertise("gz.msgs.Pose_V"))
    peer.sent.clear()
    peer.discovery.goodbye()
    assert [sent.type for sent, _ in peer.sent] == [Record.UNADVERTISE, Record.END_CONNECTION, Record.BYE]


def test_relays_get_our_datagrams_and_the_groups_and_give_theirs_to_the_group() -> None:
    """GZ_RELAY, as gz-transport relays: to a relay with RELAY set; from one, to the group with NO_RELAY."""
    peer = Peer(NodeEnvironment(relays=("10.0.0.2",)))
    peer.discovery.advertise("@/test@/drake/pose_v", "gz.msgs.Pose_V")
    (to_group, group), (to_relay, relay) = peer.sent
    assert (group, relay) == (GROUP, ("10.0.0.2", MESSAGE_PORT))
    assert not to_group.flags.relay and to_relay.flags.relay and to_relay.type == Record.ADVERTISE
    peer.sent.clear()
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    peer.sent.clear()
    relayed = advertise("gz.msgs.Pose_V")
    relayed.flags.relay = True
    peer.discovery.on_datagram(datagram(relayed), "10.0.0.9", 0.0)
    ((forwarded, where),) = peer.sent
    assert where == GROUP and forwarded.flags.no_relay and not forwarded.flags.relay
    assert not peer.connected  # read when it comes back from the group
    assert peer.discovery.relays == ("10.0.0.2", "10.0.0.9")
    peer.sent.clear()
    peer.discovery.on_datagram(datagram(forwarded), "127.0.0.1", 0.0)
    assert peer.connected == [PEER]
    # NO_RELAY: the advertisement goes no further; our NEW_CONNECTION goes to the group and relays.
    assert [sent.type for sent, _ in peer.sent] == [Record.NEW_CONNECTION] * 3
    peer.sent.clear()
    peer.receive(record(Record.HEARTBEAT))  # a plain datagram of the group: on to every relay
    assert sorted(where for _, where in peer.sent) == [("10.0.0.2", MESSAGE_PORT), ("10.0.0.9", MESSAGE_PORT)]
    assert all(sent.flags.relay for sent, _ in peer.sent)


def test_our_own_datagrams_are_ignored() -> None:
    peer = Peer()
    peer.discovery.subscribe(TOPIC, "gz.msgs.Pose_V")
    own = advertise("gz.msgs.Pose_V")
    own.process_uuid = peer.discovery.process_uuid
    assert not peer.receive(own) and not peer.connected and not peer.reported


def test_the_record_is_gz_msgs_discovery() -> None:
    assert Record is MESSAGES.Discovery
    assert (Record.SUBSCRIBERS_REQ, Record.SUBSCRIBERS_REP) == (8, 9)
