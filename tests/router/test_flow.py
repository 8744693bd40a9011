"""The mailbox between a transport's thread and a route's worker (viewer_bridge/router/flow.py)."""

from __future__ import annotations

from viewer_bridge.router.flow import Mailbox, Message
from viewer_bridge.transports.base import Received


def test_mailbox_keeps_the_newest_per_channel_and_never_grows() -> None:
    import re

    match = re.fullmatch("x", "x")
    assert match is not None
    latest = Mailbox("latest", 10)
    for index in range(1000):
        latest.put(Message(Received("DRAW", bytes([index % 256]), index), match))
    latest.put(Message(Received("LOAD", b"load", 0), match))
    latest.put(Message(Received("DRAW", b"newest", 0), match))
    assert len(latest) == 2 and (latest.superseded, latest.mailbox_full, latest.dropped) == (1000, 0, 1000)
    assert [latest.take().received.data, latest.take().received.data] == [b"load", b"newest"]  # type: ignore[union-attr]
    fifo = Mailbox("all", 3)
    for index in range(5):
        fifo.put(Message(Received("DRAW", bytes([index]), index), match))
    assert (fifo.superseded, fifo.mailbox_full, fifo.dropped) == (0, 2, 2)
    assert [fifo.take().received.data for _ in range(3)] == [b"\x02", b"\x03", b"\x04"]  # type: ignore[union-attr]
    assert fifo.take() is None and not fifo.wait(0.01)


def test_a_rate_limited_mailbox_counts_what_it_conflates_apart_from_drops() -> None:
    import re

    match = re.fullmatch("x", "x")
    assert match is not None
    limited = Mailbox("latest", 10, rate_limited=True)
    for index in range(3):
        limited.put(Message(Received("DRAW", bytes([index]), index), match))
    assert (limited.rate_skipped, limited.superseded, limited.dropped) == (2, 0, 0)


def test_the_inline_budget_lets_a_thread_translate_up_to_its_share_then_recovers() -> None:
    from viewer_bridge.router.flow import InlineBudget

    budget = InlineBudget(share=0.5, window_s=0.2)  # a burst of 0.1 s, then half the time
    now = 100.0
    assert budget.allows(now)
    budget.spent(now, now + 0.12)  # one translation longer than the burst
    now += 0.12
    assert not budget.allows(now)  # the worker takes the next messages
    assert not budget.allows(now + 0.02)
    now += 0.05
    assert budget.allows(now)  # drained at half a second a second: inline again
    for _ in range(1000):  # busy a third of the time: always inline
        assert budget.allows(now)
        budget.spent(now, now + 0.001)
        now += 0.003
