"""One route's runner (viewer_bridge/router/runner.py), driven by hand without a worker: a translator's
crash, a lazy route waking up, and what a rate limit skips."""

from __future__ import annotations

import re
import time
from typing import Any

from viewer_bridge.config import Route
from viewer_bridge.router.flow import Message
from viewer_bridge.transports.base import CallPublisher, Received


def test_a_translator_crash_skips_that_message_only() -> None:
    import re

    from viewer_bridge.config import Route
    from viewer_bridge.router.runner import RouteRunner
    from viewer_bridge.translators import LoadCache, Translator

    class Flaky(Translator):
        reads = ()
        outputs = ()

        def translate(self, message: Received) -> Any:
            if message.data == b"boom":
                raise ZeroDivisionError("a bug")
            return []

    route = Route.model_validate(
        {"name": "r", "source": {"transport": "lcm", "name": "X"}, "translator": "drake_to_pose_array",
         "destination": {"transport": "ros", "name": "/x"}}
    )  # fmt: skip
    runner = RouteRunner(route, lambda: Flaky({}, LoadCache()), lambda name, output: CallPublisher(print))
    match = re.fullmatch("X", "X")
    assert match is not None
    for data in (b"ok", b"boom", b"ok"):
        runner.handle(Message(Received("X", data, 0), match))
    assert runner.stats.errors == {"crash:ZeroDivisionError": 1} and len(runner.stats.translate_ms) == 2


def lazy_pose_route(**rate: Any) -> Route:
    return Route.model_validate(
        {"name": "r", "source": {"transport": "lcm", "name": "DRAKE_VIEWER_DRAW"}, "translator": "drake_to_pose_array",
         "destination": {"transport": "ros", "name": "/x"}, "lazy": True, "rate": rate or {"policy": "latest"}}
    )  # fmt: skip


def test_a_lazy_route_that_wakes_does_not_count_the_wait_as_latency() -> None:
    from viewer_bridge.examples.scenes import draw_of, small_scene
    from viewer_bridge.router.runner import RouteRunner
    from viewer_bridge.translators import TRANSLATORS, LoadCache

    listeners = 0
    published: list[bytes] = []
    route = lazy_pose_route()
    runner = RouteRunner(
        route,
        lambda: TRANSLATORS.get("drake_to_pose_array")({}, LoadCache()),
        lambda name, output: CallPublisher(published.append, lambda: listeners),
    )
    match = re.fullmatch("DRAKE_VIEWER_DRAW", "DRAKE_VIEWER_DRAW")
    assert match is not None
    scene = small_scene()
    five_seconds_ago = time.time_ns() // 1000 - 5_000_000
    runner.handle(Message(Received("DRAKE_VIEWER_DRAW", draw_of(scene, 1.0), five_seconds_ago), match))
    assert runner.stats.idle_skipped == 1 and not published
    listeners = 1
    deadline = time.monotonic() + 30
    while not published and time.monotonic() < deadline:  # the subscriber is noticed within 0.25 s
        runner.catch_up()
        time.sleep(0.01)
    assert len(published) == 1  # the message kept while nobody listened, translated on waking
    assert not runner.stats.latency_ms  # its five seconds of waiting are no latency
    runner.handle(Message(Received("DRAKE_VIEWER_DRAW", draw_of(scene, 2.0)), match))
    assert len(published) == 2 and len(runner.stats.latency_ms) == 1
    assert runner.stats.latency_ms[0] < 5_000


def test_messages_a_rate_limit_skips_are_counted_as_skipped_not_dropped() -> None:
    from viewer_bridge.router.runner import RouteRunner
    from viewer_bridge.translators import TRANSLATORS, LoadCache

    def runner(**rate: Any) -> RouteRunner:
        return RouteRunner(
            lazy_pose_route(**rate),
            lambda: TRANSLATORS.get("drake_to_pose_array")({}, LoadCache()),
            lambda name, output: CallPublisher(print),
        )

    for rate, dropped, skipped in (({"policy": "latest", "max_hz": 5}, 0, 2), ({"policy": "latest"}, 2, 0)):
        route = runner(**rate)
        match = re.fullmatch("D", "D")
        assert match is not None
        for index in range(3):  # queued, not taken: the worker is not started
            route.mailbox.put(Message(Received("DRAKE_VIEWER_DRAW", bytes([index])), match))
        stats = route.snapshot()
        assert (stats["dropped"], stats["max_hz_skipped"], stats["queued"]) == (dropped, skipped, 1), rate
