"""Who may connect to the Foxglove server: the front's origin check (403) and its limits per
client (503 past `max_clients`; channels and message size, refused with a status), against the
`websockets` package's client, which sends an `Origin` header only when told to. And the
front's answer to the SDK's subscribe race, against a server of that package standing for the SDK,
and against the installed foxglove-sdk's own server (tests/sdk_race.py brings the race on)."""

from __future__ import annotations

import contextlib
import json
import logging
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from foxglove import Context, start_server
from pydantic import ValidationError
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import ClientConnection, connect
from websockets.sync.server import ServerConnection, serve
from websockets.typing import Origin, Subprotocol

from tests.fuzz.targets import RecordingConnection
from tests.sdk_race import ChannelMaker, EagerClient, Subscribers, making_channels
from viewer_bridge.errors import HandshakeError
from viewer_bridge.transports import foxglove_front
from viewer_bridge.transports.base import CDR, MessageType, Qos, Received
from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport
from viewer_bridge.transports.foxglove_clients import ClientPublishing
from viewer_bridge.transports.foxglove_front import (
    MAX_SUBSCRIPTIONS,
    RESUBSCRIBE_DELAYS,
    Resubscriptions,
    SubprotocolFront,
)
from viewer_bridge.transports.origins import FOXGLOVE_APPS, Origins
from viewer_bridge.transports.sdk_tls import SdkCertificate, SdkLink
from viewer_bridge.transports.websocket_frames import BINARY, MAX_FRAGMENTS, TEXT, Message

NAMES = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
WAIT = 60.0
EVIL = "https://evil.example"


def open_client(port: int, origin: str | None, name: str = "foxglove.sdk.v1") -> ClientConnection:
    """A client that has its serverInfo; raises InvalidStatus when the server refuses it."""
    ws = connect(f"ws://127.0.0.1:{port}", origin=Origin(origin) if origin else None,
                 subprotocols=[Subprotocol(name)], open_timeout=WAIT).__enter__()  # fmt: skip
    assert ws.subprotocol == name
    assert json.loads(ws.recv(timeout=WAIT))["op"] == "serverInfo"
    return ws


def refused(port: int, origin: str | None, name: str = "foxglove.sdk.v1") -> tuple[int, str]:
    """The status and body a refused handshake gets (fails when it is accepted)."""
    with pytest.raises(InvalidStatus) as caught:
        open_client(port, origin, name).close()
    response = caught.value.response
    return response.status_code, response.body.decode() if response.body else ""


def wait_until(condition: Callable[[], bool], seconds: float = WAIT) -> bool:
    deadline = time.monotonic() + seconds
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.02)
    return condition()


@pytest.fixture
def foxglove() -> Iterator[Callable[..., FoxgloveTransport]]:
    """Makes Foxglove transports on free ports with the settings given; closes them after the test."""
    made: list[FoxgloveTransport] = []

    def make(**settings: Any) -> FoxgloveTransport:
        made.append(FoxgloveTransport(FoxgloveSettings(port=0, **settings)))
        return made[-1]

    yield make
    for transport in made:
        transport.close()


# --- The origin check ------------------------------------------------------------------------------------


def test_a_page_of_a_foreign_origin_gets_403_on_both_names_and_the_sdk_sees_nothing(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # A plain listener stands for the SDK's server: the front connects to it only to relay a client.
    with socket.create_server(("127.0.0.1", 0)) as sdk:
        front = SubprotocolFront("127.0.0.1", 0, sdk.getsockname()[1])
        try:
            with caplog.at_level(logging.WARNING, logger="viewer_bridge"):
                for name in NAMES:
                    status, body = refused(front.port, EVIL, name)
                    assert status == 403
                    assert f'allow it with foxglove.allowed_origins: ["{EVIL}"]' in body
                assert refused(front.port, "http://other.example:8080")[0] == 403
            # The front answers before it would connect to the SDK: by now, a connection would be waiting.
            sdk.setblocking(False)
            with pytest.raises(BlockingIOError):
                sdk.accept()
            assert front.errors() == {"origin_refused": 3}
            lines = [
                record.getMessage() for record in caplog.records if "refused (403)" in record.getMessage()
            ]
            assert lines == [  # one line per distinct origin
                f'foxglove client from origin {EVIL} refused (403): allow it with foxglove.allowed_origins: ["{EVIL}"]',
                "foxglove client from origin http://other.example:8080 refused (403): allow it with "
                'foxglove.allowed_origins: ["http://other.example:8080"]',
            ]
        finally:
            front.close()


def test_the_refusal_is_a_whole_http_response_and_the_connection_ends() -> None:
    with socket.create_server(("127.0.0.1", 0)) as sdk:
        front = SubprotocolFront("127.0.0.1", 0, sdk.getsockname()[1])
        try:
            with socket.create_connection(("127.0.0.1", front.port), timeout=WAIT) as raw:
                raw.sendall(b"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                            b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                            b"Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n"
                            b"Origin: https://evil.example\r\n\r\n")  # fmt: skip
                answer = b""
                while chunk := raw.recv(4096):  # read until the front closes
                    answer += chunk
            head, _, body = answer.partition(b"\r\n\r\n")
            lines = head.decode().split("\r\n")
            assert lines[0] == "HTTP/1.1 403 Forbidden"
            assert f"Content-Length: {len(body)}" in lines and "Connection: close" in lines
            assert body.decode().startswith("foxglove client from origin https://evil.example refused (403)")
        finally:
            front.close()


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_clients_without_an_origin_foxgloves_app_and_loopback_pages_get_through(
    foxglove: Callable[..., FoxgloveTransport], name: str
) -> None:
    transport = foxglove()
    for origin in (None, "https://app.foxglove.dev", "https://studio.foxglove.dev", "http://localhost:3000",
                   "http://localhost", "http://127.0.0.1:8080", "https://[::1]:5173", "http://[::1]"):  # fmt: skip
        open_client(transport.port, origin, name).close()
    assert refused(transport.port, "http://localhost.evil.example", name)[0] == 403
    assert refused(transport.port, "null", name)[0] == 403  # a file:// page or a sandboxed frame
    assert transport.errors() == {"origin_refused": 2}
    assert "origin check off" not in transport.describe()


@pytest.mark.slow
def test_allowed_origins_add_exact_origins_and_patterns(foxglove: Callable[..., FoxgloveTransport]) -> None:
    transport = foxglove(allowed_origins=["https://lab.example", "https://*.corp.example"])
    for origin in ("https://lab.example", "https://viewer.corp.example", "https://a.b.corp.example",
                   "http://localhost:3000", "https://app.foxglove.dev"):  # fmt: skip
        open_client(transport.port, origin).close()
    for origin in (EVIL, "https://lab.example:8443", "http://lab.example", "https://corp.example",
                   "https://viewer.corp.example.evil"):  # fmt: skip
        assert refused(transport.port, origin)[0] == 403, origin
    assert transport.errors() == {"origin_refused": 5}


@pytest.mark.slow
def test_a_lone_star_lets_every_page_in_and_the_start_up_line_says_so(
    foxglove: Callable[..., FoxgloveTransport],
) -> None:
    transport = foxglove(allowed_origins=["*"])
    for name in NAMES:
        open_client(transport.port, EVIL, name).close()
    assert transport.errors() == {}
    assert "origin check off" in transport.describe()


def test_the_origin_rules() -> None:
    foxglove = Origins(trusted=FOXGLOVE_APPS)
    assert foxglove.allows(None) and foxglove.allows("HTTPS://APP.FOXGLOVE.DEV")  # case of scheme and host
    assert foxglove.allows("https://localhost:1") and foxglove.allows("http://[::1]:65535")
    assert not foxglove.allows("https://app.foxglove.dev.evil.example")
    assert not foxglove.allows("http://127.0.0.1.evil.example") and not foxglove.allows("http://[::2]")
    # Every character but * is itself: brackets are no class, a dot no wildcard.
    lab = Origins(["https://[ab].example", "https://a.b:*"])
    assert lab.allows("https://[ab].example") and not lab.allows("https://a.example")
    assert lab.allows("https://a.b:8443") and not lab.allows("https://aXb:8443")
    # A * spans no /.
    assert Origins(["https://*.example"]).allows("https://x.example")
    assert not Origins(["https://*.example"]).allows("https://x/y.example")


def test_an_allowed_origin_with_a_path_is_refused_in_the_config() -> None:
    with pytest.raises(ValidationError, match="'https://lab.example/' is no origin"):
        FoxgloveSettings(allowed_origins=["https://lab.example/"])
    assert (
        FoxgloveSettings(allowed_origins=["*", "null", "https://*.lab.example:*"]).allowed_origins[0] == "*"
    )


@pytest.mark.slow
def test_the_front_checks_origins_even_when_it_renames_and_reads_nothing(
    foxglove: Callable[..., FoxgloveTransport],
) -> None:
    transport = foxglove(accept_websocket_v1=False, client_publish=False)
    assert refused(transport.port, EVIL)[0] == 403
    open_client(transport.port, None).close()
    status, body = refused(transport.port, None, "foxglove.websocket.v1")
    assert status == 400 and "sec-websocket-protocol" in body  # not renamed: the SDK's whole refusal, unread


# --- The limits per client --------------------------------------------------------------------------------


@pytest.mark.slow
def test_one_client_past_max_clients_gets_503_until_one_leaves(
    foxglove: Callable[..., FoxgloveTransport], caplog: pytest.LogCaptureFixture
) -> None:
    transport = foxglove(max_clients=2)
    first, second = open_client(transport.port, None), open_client(transport.port, None)
    try:
        with caplog.at_level(logging.WARNING, logger="viewer_bridge"):
            for _ in range(2):
                status, body = refused(transport.port, None, "foxglove.websocket.v1")
                assert status == 503 and "raise foxglove.max_clients" in body
        assert transport.errors() == {"too_many_clients": 2}
        assert len([record for record in caplog.records if "(503)" in record.getMessage()]) == 1  # said once
        first.close()
        assert wait_until(lambda: transport.front.clients() == 1)
        open_client(transport.port, None).close()  # the place it left is free
    finally:
        first.close()
        second.close()


def statuses(ws: ClientConnection, *words: str) -> str:
    """The first of the bridge's error statuses naming all of `words` (read until it comes)."""
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        frame = ws.recv(timeout=max(0.01, deadline - time.monotonic()))
        if isinstance(frame, str):
            message: dict[str, Any] = json.loads(frame)
            text = message.get("message", "")
            if (
                message["op"] == "status"
                and text.startswith("viewer-bridge:")
                and all(word in text for word in words)
            ):
                return str(text)
    raise AssertionError(f"no status naming {words}")


@pytest.mark.slow
def test_a_client_past_its_channel_limit_or_message_size_hears_why(
    foxglove: Callable[..., FoxgloveTransport],
) -> None:
    transport = foxglove(max_client_channels=2, max_client_message_bytes=2048)
    delivered: list[Received] = []
    transport.subscribe("/lcm_in/(.*)", MessageType("*", CDR), Qos(), delivered.append)
    ws = open_client(transport.port, None)
    try:
        channels = [{"id": index, "topic": f"/lcm_in/C{index}", "encoding": "json", "schemaName": "std_msgs/msg/Empty"}
                    for index in (1, 2, 3)]  # fmt: skip
        ws.send(json.dumps({"op": "advertise", "channels": channels}))
        assert "at most 2 channels" in statuses(ws, "foxglove.max_client_channels")
        ws.send(b"\x01" + struct.pack("<I", 1) + b"x" * 4096)
        assert "longer than 2048 bytes" in statuses(ws, "foxglove.max_client_message_bytes")
        ws.send(b"\x01" + struct.pack("<I", 2) + b"{}")  # within the limits: delivered
        assert wait_until(lambda: len(delivered) == 1)
        assert delivered[0].channel == "/lcm_in/C2"
        assert transport.errors() == {"client_channel_limit": 1, "client_message_unread": 1}
    finally:
        ws.close()


def test_what_a_client_leaves_behind_is_bounded_and_forgotten_when_it_goes() -> None:
    publishing = ClientPublishing(max_channels=4)
    publishing.subscribe("/lcm_in/(.*)", lambda received: None)
    connection = RecordingConnection()
    for index in range(3000):  # each channel refused with a status of its own, then withdrawn
        advertised = {"id": index, "topic": f"/lcm_in/T{index}", "encoding": "protobuf", "schemaName": "x"}
        publishing.message(
            connection, Message(TEXT, json.dumps({"op": "advertise", "channels": [advertised]}).encode())
        )
        publishing.message(
            connection, Message(TEXT, json.dumps({"op": "unadvertise", "channelIds": [index]}).encode())
        )
    assert len(connection.said) == 3000 and publishing.remembered() == (0, 1000)  # the most recent kept
    huge = {"id": 1, "topic": "/lcm_in/" + "x" * 1_000_000, "encoding": "protobuf"}
    publishing.message(
        connection, Message(TEXT, json.dumps({"op": "advertise", "channels": [huge]}).encode())
    )
    assert len(json.loads(connection.said[-1])["message"]) < 1100  # a megabyte topic is not repeated whole
    publishing.message(connection, Message(BINARY, b"", "longer than 2048 bytes"))
    publishing.closed(connection)
    assert publishing.remembered() == (0, 0)


# --- A subscription the SDK refuses before it has listed the channel it advertised ---------------------


class RacingSdk:
    """Stands for the SDK's server at its race (foxglove_front.Resubscriptions): it advertises
    channels 1 and 2, answers the first `refusals` subscriptions of channel 2 with the SDK's error
    status as if the channel were not listed yet, and sends one message on each subscription it
    takes. What it was asked is kept, the ops as received."""

    def __init__(self, refusals: int, advertised: tuple[int, ...] = (1, 2)) -> None:
        self.refusals = refusals
        self.advertised = advertised
        self.asked: list[dict[str, Any]] = []
        self._server = serve(
            self._serve, "127.0.0.1", 0, subprotocols=[Subprotocol("foxglove.sdk.v1")], compression=None
        )  # fmt: skip  (the SDK's WebSocket library offers no compression)
        self.port = self._server.socket.getsockname()[1]
        threading.Thread(target=self._server.serve_forever, daemon=True).start()

    def _serve(self, ws: ServerConnection) -> None:
        ws.send(json.dumps({"op": "serverInfo", "name": "racing", "capabilities": []}))
        channels = [{"id": each, "topic": f"/t{each}", "encoding": "json", "schemaName": "x", "schema": ""}
                    for each in self.advertised]  # fmt: skip
        ws.send(json.dumps({"op": "advertise", "channels": channels}))
        for text in ws:
            op = json.loads(text)
            self.asked.append(op)
            for subscription in op.get("subscriptions", []):
                channel = subscription["channelId"]
                if channel not in (1, 2) or (channel == 2 and self.refusals > 0):
                    self.refusals -= channel == 2
                    ws.send(
                        json.dumps({"op": "status", "level": 2, "message": f"Unknown channel ID: {channel}"})
                    )
                else:
                    ws.send(b"\x01" + struct.pack("<IQ", subscription["id"], 0) + f"on {channel}".encode())

    def close(self) -> None:
        self._server.shutdown()


def until_data(ws: ClientConnection, subscription: int) -> list[str | bytes]:
    """What a client receives up to the message data of `subscription`."""
    received: list[str | bytes] = []
    while not (
        received and isinstance(received[-1], bytes) and received[-1][1:5] == struct.pack("<I", subscription)
    ):
        received.append(ws.recv(timeout=WAIT))
    return received


@pytest.fixture
def racing() -> Iterator[Callable[..., tuple[RacingSdk, SubprotocolFront]]]:
    """Makes a RacingSdk and a front before it; closes both after the test."""
    made: list[tuple[RacingSdk, SubprotocolFront]] = []

    def make(refusals: int, advertised: tuple[int, ...] = (1, 2)) -> tuple[RacingSdk, SubprotocolFront]:
        sdk = RacingSdk(refusals, advertised)
        made.append((sdk, SubprotocolFront("127.0.0.1", 0, sdk.port)))
        return made[-1]

    yield make
    for sdk, front in made:
        front.close()
        sdk.close()


@pytest.mark.parametrize("name", NAMES)
def test_a_subscription_the_sdk_refused_too_early_is_sent_again_and_the_client_never_sees_the_error(
    racing: Callable[..., tuple[RacingSdk, SubprotocolFront]], name: str
) -> None:
    sdk, front = racing(refusals=1)
    with connect(f"ws://127.0.0.1:{front.port}", subprotocols=[Subprotocol(name)], open_timeout=WAIT) as ws:
        assert json.loads(ws.recv(timeout=WAIT))["op"] == "serverInfo"
        assert json.loads(ws.recv(timeout=WAIT))["op"] == "advertise"
        # Both at once, the moment they are advertised, as the app subscribes.
        ws.send(
            json.dumps(
                {"op": "subscribe", "subscriptions": [{"id": 7, "channelId": 1}, {"id": 8, "channelId": 2}]}
            )
        )
        received = until_data(ws, 8)
    assert received[-1] == b"\x01" + struct.pack("<IQ", 8, 0) + b"on 2"
    assert not [each for each in received if isinstance(each, str)]  # the error status was held back
    # the front's, masked
    assert sdk.asked[1] == {"op": "subscribe", "subscriptions": [{"id": 8, "channelId": 2}]}
    assert front.errors() == {"resubscribed": 1}


def test_after_its_last_attempt_the_status_reaches_the_client(
    racing: Callable[..., tuple[RacingSdk, SubprotocolFront]],
) -> None:
    # the last refuses the client's own second subscribe
    sdk, front = racing(refusals=len(RESUBSCRIBE_DELAYS) + 2)
    with connect(
        f"ws://127.0.0.1:{front.port}", subprotocols=[Subprotocol("foxglove.sdk.v1")], open_timeout=WAIT
    ) as ws:
        ws.recv(timeout=WAIT), ws.recv(timeout=WAIT)  # serverInfo, advertise
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 8, "channelId": 2}]}))
        status = json.loads(ws.recv(timeout=WAIT))
        assert status == {"op": "status", "level": 2, "message": "Unknown channel ID: 2"}
        # The client subscribing again itself is a new subscription: the front tries again for it.
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 8, "channelId": 2}]}))
        received = until_data(ws, 8)
    assert not [each for each in received if isinstance(each, str)]
    assert len(sdk.asked) == 1 + len(RESUBSCRIBE_DELAYS) + 1 + 1
    assert front.errors() == {"resubscribed": len(RESUBSCRIBE_DELAYS) + 1}


def test_a_channel_never_advertised_or_unsubscribed_meanwhile_gets_the_sdks_answer(
    racing: Callable[..., tuple[RacingSdk, SubprotocolFront]],
) -> None:
    sdk, front = racing(refusals=1, advertised=(1,))
    with connect(
        f"ws://127.0.0.1:{front.port}", subprotocols=[Subprotocol("foxglove.sdk.v1")], open_timeout=WAIT
    ) as ws:
        ws.recv(timeout=WAIT), ws.recv(timeout=WAIT)  # serverInfo, advertise of channel 1 alone
        ws.send(
            json.dumps(
                {"op": "subscribe", "subscriptions": [{"id": 8, "channelId": 2}, {"id": 9, "channelId": 3}]}
            )
        )
        answers = [json.loads(ws.recv(timeout=WAIT))["message"] for _ in range(2)]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": 1}]}))
        until_data(ws, 7)  # everything before it has been through the front
    assert answers == ["Unknown channel ID: 2", "Unknown channel ID: 3"]
    assert len(sdk.asked) == 2 and front.errors() == {}


def test_what_a_client_leaves_for_resubscribing_is_bounded() -> None:
    subscriptions = Resubscriptions()
    for index in range(3 * MAX_SUBSCRIPTIONS):
        subscribe = {"op": "subscribe", "subscriptions": [{"id": index, "channelId": index}]}
        subscriptions.client_said(json.dumps(subscribe).encode())
        subscriptions.server_said(json.dumps({"op": "advertise", "channels": [{"id": index}]}).encode())
    assert subscriptions.remembered() == (MAX_SUBSCRIPTIONS, MAX_SUBSCRIPTIONS)
    oldest, newest = (json.dumps({"op": "status", "level": 2, "message": f"Unknown channel ID: {channel}"}).encode()
                      for channel in (0, 3 * MAX_SUBSCRIPTIONS - 1))  # fmt: skip
    assert subscriptions.server_said(oldest) is None  # forgotten: its status passes
    assert subscriptions.server_said(newest) == (3 * MAX_SUBSCRIPTIONS - 1, RESUBSCRIBE_DELAYS[0])
    for junk in (b"\xff", b"[]", b'{"op": "subscribe", "subscriptions": [{"id": true, "channelId": -1}, 5]}',
                 b'{"op": "unsubscribe", "subscriptionIds": "all"}', b"[" * 100_000):  # fmt: skip
        subscriptions.client_said(junk)
        assert subscriptions.server_said(junk) is None
    subscriptions.client_said(b'{"op": "unsubscribe", "subscriptionIds": [%d]}' % (3 * MAX_SUBSCRIPTIONS - 1))
    assert subscriptions.server_said(newest) is None  # nothing of the client's left to send again


# --- The same race on the installed foxglove-sdk's own server (tests/sdk_race.py provokes it) ----------


@pytest.fixture
def sdk_server() -> Iterator[tuple[Context, Subscribers, int]]:
    """A foxglove-sdk server on a context of its own: the context, what it took subscriptions of,
    and its port."""
    context, subscribers = Context(), Subscribers()
    server = start_server(host="127.0.0.1", port=0, context=context, server_listener=subscribers)
    yield context, subscribers, server.port
    server.stop()


def test_the_sdk_drops_a_subscription_sent_the_moment_its_channel_is_advertised(
    sdk_server: tuple[Context, Subscribers, int],
) -> None:
    """Without the front: the race the front repairs, shown on the SDK's server (if this fails
    with nothing refused, the SDK may have fixed its race: the front's repair could go)."""
    context, subscribers, port = sdk_server
    maker = ChannelMaker(context, 40)
    client = EagerClient(port)
    try:
        with making_channels(maker):
            pass
        # Every subscription answered one way or the other: taken, or refused with the status.
        assert wait_until(lambda: subscribers.subscribed() | set(client.refused()) == maker.topics), (
            subscribers.subscribed(),
            client.statuses,
        )
        refused = client.refused()
    finally:
        client.close()
    assert refused, "no subscription of an advertised channel was refused"
    assert not set(refused) & subscribers.subscribed()  # dropped: the SDK's listener never heard of them


def test_through_the_front_every_subscription_sent_the_moment_its_channel_is_advertised_is_taken(
    sdk_server: tuple[Context, Subscribers, int],
) -> None:
    context, subscribers, port = sdk_server
    front = SubprotocolFront("127.0.0.1", 0, port)
    maker = ChannelMaker(context, 40)
    client = EagerClient(front.port)
    try:
        with making_channels(maker):
            pass
        assert wait_until(lambda: subscribers.subscribed() == maker.topics), (
            sorted(maker.topics - subscribers.subscribed()),
            client.statuses,
        )
        assert client.statuses == []  # no error reached the client
        assert front.errors().get("resubscribed", 0) >= 1  # the race happened, and was repaired
    finally:
        client.close()
        front.close()


def test_the_front_reads_the_sdks_own_words_for_an_unknown_channel(
    sdk_server: tuple[Context, Subscribers, int],
) -> None:
    """The front knows the refusal by the text and level of the SDK's status: if a new SDK says
    it otherwise, this fails (and the repair would silently stop working)."""
    _, _, port = sdk_server
    channel = 4_000_000  # never made: the SDK answers as it does in its race
    with connect(
        f"ws://127.0.0.1:{port}", subprotocols=[Subprotocol("foxglove.sdk.v1")], open_timeout=WAIT
    ) as ws:
        assert json.loads(ws.recv(timeout=WAIT))["op"] == "serverInfo"
        subscribe = json.dumps({"op": "subscribe", "subscriptions": [{"id": 8, "channelId": channel}]})
        ws.send(subscribe)
        status = ws.recv(timeout=WAIT)
    assert isinstance(status, str)
    subscriptions = Resubscriptions()  # as if the SDK had advertised the channel to this client
    subscriptions.server_said(json.dumps({"op": "advertise", "channels": [{"id": channel}]}).encode())
    subscriptions.client_said(subscribe.encode())
    assert subscriptions.server_said(status.encode()) == (channel, RESUBSCRIBE_DELAYS[0]), status


# --- Hostile connections at the door (issue 51) -------------------------------------------------------------


def _gone(sock: socket.socket, seconds: float) -> bool:
    """Whether the other end closed `sock` within `seconds` (what it sent before is read past)."""
    sock.settimeout(seconds)
    try:
        while sock.recv(4096):
            pass
    except TimeoutError:
        return False
    except OSError:  # reset
        pass
    return True


def test_a_request_trickled_in_is_dropped_at_one_deadline_for_the_whole_head(
    foxglove: Callable[..., FoxgloveTransport], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A byte every 0.3 s keeps each read well within the deadline; the head as a whole is not,
    and its connection is dropped once the deadline has passed."""
    monkeypatch.setattr(foxglove_front, "HANDSHAKE_SECONDS", 1.5)
    transport = foxglove()
    head = b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n" + b"X-Padding: " + b"x" * 200
    with socket.create_connection(("127.0.0.1", transport.port), timeout=WAIT) as slow:
        start = time.monotonic()
        closed = False
        for byte in head:
            with contextlib.suppress(OSError):
                slow.sendall(bytes([byte]))
            if _gone(slow, 0.3):
                closed = True
                break
        assert closed, "still open after its whole trickle"
        assert 1.5 <= time.monotonic() - start < WAIT
    assert wait_until(lambda: transport.errors().get("bad_handshake") == 1)


def test_past_max_handshakes_the_oldest_request_under_way_is_dropped_and_a_client_still_gets_in(
    foxglove: Callable[..., FoxgloveTransport],
) -> None:
    """Requests under way hold no thread each and at most `max_handshakes` files: one more
    pushes the oldest out, so a crowd of stalled connections never keeps a client out."""
    transport = foxglove()
    transport.front.max_handshakes = 8
    threads = threading.active_count()
    stalled = [socket.create_connection(("127.0.0.1", transport.port), timeout=WAIT) for _ in range(30)]
    try:
        for sock in stalled:
            sock.sendall(b"G")
        assert wait_until(lambda: transport.errors().get("too_many_handshakes") == 22)
        assert transport.front.handshakes() == 8 and threading.active_count() <= threads
        assert sum(_gone(sock, 0.01) for sock in stalled) == 22
        open_client(transport.port, None).close()  # newest: read before the next crowd pushes it out
    finally:
        for sock in stalled:
            sock.close()


@pytest.mark.filterwarnings(
    "ignore::pytest.PytestUnhandledThreadExceptionWarning"
)  # the end it is made to meet
def test_an_accepting_thread_that_ends_is_started_again_and_said(
    foxglove: Callable[..., FoxgloveTransport], caplog: pytest.LogCaptureFixture
) -> None:
    transport = foxglove()
    front = transport.front
    accept = front._accept_waiting
    ended = threading.Event()

    def ends_once(selector: Any) -> None:
        if not ended.is_set():
            ended.set()
            raise SystemExit  # what no `except Exception` catches: the thread ends
        accept(selector)

    front._accept_waiting = ends_once  # type: ignore[method-assign]
    with caplog.at_level(logging.ERROR, logger="viewer_bridge"):
        open_client(transport.port, None).close()  # waits in the queue while the thread starts again
    assert ended.is_set() and transport.errors().get("accept_restarted") == 1
    assert [
        record for record in caplog.records if "accepting thread ended: started again" in record.getMessage()
    ]


OUT_OF_FILES = """
import logging, os, resource, sys
logging.basicConfig(level=logging.WARNING)
resource.setrlimit(resource.RLIMIT_NOFILE, (256, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
from viewer_bridge.transports.foxglove import FoxgloveSettings, FoxgloveTransport
transport = FoxgloveTransport(FoxgloveSettings(port=0))
print(transport.port, flush=True)
held = []
try:
    while True:
        held.append(os.open(os.devnull, os.O_RDONLY))
except OSError:
    pass
print("full", flush=True)
sys.stdin.readline()
for each in held:
    os.close(each)
print("freed", flush=True)
sys.stdin.readline()
print(transport.errors().get("out_of_files", 0), flush=True)
transport.close()
"""


@pytest.mark.e2e
def test_out_of_files_the_front_rests_says_so_and_serves_again_once_files_are_free() -> None:
    """A bridge process whose files are all taken: the connections that come meanwhile are
    refused or wait, the front says so (a few lines, not one per try), and once files are free
    a client is served (accepting never stopped for good)."""
    child = subprocess.Popen([sys.executable, "-c", OUT_OF_FILES], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)  # fmt: skip
    assert child.stdin is not None and child.stdout is not None
    try:
        port = int(child.stdout.readline())
        assert child.stdout.readline() == "full\n"
        tries = [socket.create_connection(("127.0.0.1", port), timeout=WAIT) for _ in range(20)]
        for sock in tries:
            with contextlib.suppress(OSError):
                sock.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
        time.sleep(1.0)  # the front meets a full table a few times (nothing to wait on: it serves no one)
        child.stdin.write("\n")
        child.stdin.flush()
        assert child.stdout.readline() == "freed\n"
        open_client(port, None).close()
        for sock in tries:
            sock.close()
        child.stdin.write("\n")
        child.stdin.flush()
        assert int(child.stdout.readline()) >= 1
    finally:
        child.stdin.close()
        child.wait(timeout=WAIT)
        assert child.stderr is not None
        errors = child.stderr.read()
    said = [line for line in errors.splitlines() if "no file for a new foxglove client" in line]
    assert 1 <= len(said) <= 2, errors
    assert "Traceback" not in errors, errors


def test_a_client_sending_a_message_in_too_many_fragments_is_let_go_and_others_are_served(
    foxglove: Callable[..., FoxgloveTransport],
) -> None:
    transport = foxglove()
    bad, good = open_client(transport.port, None), open_client(transport.port, None)
    try:
        bad.send(["x"] * (MAX_FRAGMENTS + 10))  # one text message, a frame per character
        with pytest.raises(ConnectionClosed):
            while True:
                bad.recv(timeout=WAIT)
        assert transport.errors().get("frame_limit") == 1
        good.send(json.dumps({"op": "subscribe", "subscriptions": []}))
        good.ping().wait(timeout=WAIT)
        open_client(transport.port, None).close()
    finally:
        bad.close()
        good.close()


def test_the_front_talks_only_to_the_server_with_its_own_certificate(
    foxglove: Callable[..., FoxgloveTransport],
) -> None:
    transport = foxglove()
    with pytest.raises(HandshakeError, match="another certificate"):
        SdkLink.open(transport.server.port, SdkCertificate.make(), WAIT)
