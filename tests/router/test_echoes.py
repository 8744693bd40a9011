"""The loop guard (viewer_bridge/router/echoes.py): a payload the bridge sent on a name it also
reads is recognised once when it comes back, with where it came from; anything else goes on."""

from __future__ import annotations

import pytest

from tests.peers import wait_for
from viewer_bridge.router import echoes
from viewer_bridge.router.echoes import Echoes, EchoGuard, GuardedPublisher
from viewer_bridge.shared import MessageTime
from viewer_bridge.transports.base import CallPublisher, Received

LCM_X = ("lcm", "X")


def test_a_sent_payload_is_recognised_once_with_its_origin() -> None:
    guard = EchoGuard()
    guard.sent(b"command", LCM_X)
    echo = Received("/X", b"command")
    assert guard.origin(echo) == LCM_X
    assert guard.origin(echo) == LCM_X  # the same message, asked by a second route: the same answer
    # Consume-once: a second identical message (another node's) is not the bridge's.
    assert guard.origin(Received("/X", b"command")) is None
    assert guard.origin(Received("/X", b"other")) is None


def test_each_send_matches_one_message_in_order() -> None:
    guard = EchoGuard()
    guard.sent(b"same", ("lcm", "A"))
    guard.sent(b"same", ("lcm", "B"))
    assert [guard.origin(Received("/X", b"same")) for _ in range(3)] == [("lcm", "A"), ("lcm", "B"), None]


def test_a_send_not_heard_back_is_forgotten_after_the_window() -> None:
    guard = EchoGuard(window=0.05)
    guard.sent(b"lost", LCM_X)
    # Asked with fresh messages until the send has expired: never on a fixed sleep.
    assert wait_for(lambda: guard.origin(Received("/X", b"lost")) is None, timeout=30)
    guard.sent(b"lost", LCM_X)  # a new send is remembered again
    assert guard.origin(Received("/X", b"lost")) == LCM_X


def test_a_failed_send_is_not_waited_for() -> None:
    def refuse(data: bytes) -> None:
        raise OSError("refused")

    guard = EchoGuard()
    sending = MessageTime()
    publisher = GuardedPublisher(CallPublisher(refuse), guard, "lcm", sending)
    with pytest.raises(OSError):
        publisher.publish(b"payload")
    assert guard.origin(Received("/X", b"payload")) is None


def test_a_flood_keeps_only_the_newest_sends(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(echoes, "LIMIT", 3)
    guard = EchoGuard()
    for index in range(5):
        guard.sent(b"%d" % index, LCM_X)
    assert [guard.origin(Received("/X", b"%d" % index)) for index in range(5)] == [
        None,
        None,
        LCM_X,
        LCM_X,
        LCM_X,
    ]


def test_only_names_both_published_and_read_are_guarded_and_the_origin_is_the_sending_message() -> None:
    sending = MessageTime()
    router_echoes = Echoes(sending)
    sent: list[bytes] = []
    plain = CallPublisher(sent.append)
    assert router_echoes.publisher("ros", "/lcm/X", plain, "lcm", subscribed=False) is plain  # nothing paid
    guarded = router_echoes.publisher("ros", "/X", plain, "lcm", subscribed=True)
    offered: list[Received] = []
    back: list[tuple[Received, tuple[str, str]]] = []
    deliver = router_echoes.deliver(
        "ros", offered.append, lambda message, origin: back.append((message, origin))
    )
    sending.message = Received("X", b"lcm")  # what the runner sets before it publishes a message's outputs
    guarded.publish(b"cdr")
    assert sent == [b"cdr"]
    echo, other, elsewhere = Received("/X", b"cdr"), Received("/X", b"cdr"), Received("/Y", b"cdr")
    for message in (echo, other, elsewhere):
        deliver(message)
    assert back == [(echo, ("lcm", "X"))]
    assert offered == [other, elsewhere]
