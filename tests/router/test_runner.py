"""One route's runner (viewer_bridge/router/runner.py), driven by hand without a worker: a translator's
crash, a lazy route waking up, and what a rate limit skips."""

from __future__ import annotations

import re
import time
from typing import Any

from viewer_bridge.config.bridge import Route
from viewer_bridge.router.flow import Message
from viewer_bridge.transports.base import CallPublisher, Received


def test_a_translator_crash_skips_that_message_only() -> None:
    import re

    from viewer_bridge.config.bridge import Route
    from viewer_bridge.router.runner import RouteRunner
    from viewer_bridge.translators.base import Translator

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
    runner = RouteRunner(route, lambda: Flaky({}), lambda name, output: CallPublisher(print))
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
    from viewer_bridge.translators.registry import TRANSLATORS

    listeners = 0
    published: list[bytes] = []
    route = lazy_pose_route()
    runner = RouteRunner(
        route,
        lambda: TRANSLATORS.get("drake_to_pose_array")({}),
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
    from viewer_bridge.translators.registry import TRANSLATORS

    def runner(**rate: Any) -> RouteRunner:
        return RouteRunner(
            lazy_pose_route(**rate),
            lambda: TRANSLATORS.get("drake_to_pose_array")({}),
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


def generic_route(lazy: bool) -> Route:
    return Route.model_validate(
        {"name": "bus", "source": {"transport": "lcm", "name": "(.*)"}, "translator": "lcm_to_ros",
         "destination": {"transport": "zenoh", "name": "/lcm/{1:topic}"}, "lazy": lazy, "rate": {"policy": "all"}}
    )  # fmt: skip


def test_held_messages_are_counted_per_channel_said_once_and_the_other_channels_go_on(
    caplog: Any,
) -> None:
    import drake as drake_lcmtypes

    from viewer_bridge.errors import Held
    from viewer_bridge.router.runner import RouteRunner
    from viewer_bridge.shared import Shared
    from viewer_bridge.translators.base import Output
    from viewer_bridge.translators.registry import TRANSLATORS

    shared = Shared()  # the project's types and Drake's
    published: dict[str, list[bytes]] = {}
    # As a transport may say of an interface not built yet: at once (no publisher), or on publishing.
    building = {"drake_lcm_msgs/msg/LcmtIiwaCommand"}
    unmade = {"drake_lcm_msgs/msg/LcmtSchunkWsgStatus"}

    def publisher_for(name: str, output: Output) -> CallPublisher:
        if output.type.name in unmade:
            raise Held("waiting_for_build", f"{output.type.name} is being built")

        def publish(data: bytes) -> None:
            if output.type.name in building:
                raise Held("waiting_for_build", f"{output.type.name} is being built")
            published.setdefault(name, []).append(data)

        return CallPublisher(publish, lambda: 1)

    def make() -> Any:
        return TRANSLATORS.get("lcm_to_ros")({}, shared=shared)

    runner = RouteRunner(generic_route(lazy=True), make, publisher_for)
    status = drake_lcmtypes.lcmt_iiwa_status().encode()
    command = drake_lcmtypes.lcmt_iiwa_command().encode()
    gripper = drake_lcmtypes.lcmt_schunk_wsg_status().encode()
    unknown = b"\x01\x02\x03\x04\x05\x06\x07\x08rest"
    with caplog.at_level("WARNING", logger="viewer_bridge"):
        for _ in range(3):
            for channel, data in (("IIWA_STATUS", status), ("MYSTERY", unknown), ("IIWA_COMMAND", command),
                                  ("WSG_STATUS", gripper)):  # fmt: skip
                match = re.fullmatch("(.*)", channel)
                assert match is not None
                runner.handle(Message(Received(channel, data), match))
    assert len(published["/lcm/IIWA_STATUS"]) == 3  # the known channel flows
    assert runner.stats.held == {"MYSTERY": {"unknown_type": 3}, "IIWA_COMMAND": {"waiting_for_build": 3},
                                 "WSG_STATUS": {"waiting_for_build": 3}}  # fmt: skip
    runner.catch_up()  # a lane whose publisher cannot be made is passed over, not raised
    assert not runner.stats.errors
    said = [
        record.getMessage() for record in caplog.records if "counted, not said again" in record.getMessage()
    ]
    assert len(said) == 3 and any("MYSTERY" in line and "0102030405060708" in line for line in said)
    snapshot = runner.snapshot()
    assert list(snapshot["held"]) == ["IIWA_COMMAND", "MYSTERY", "WSG_STATUS"]  # sorted by channel


def test_a_lazy_generic_route_announces_each_channels_topic_before_anyone_listens() -> None:
    import drake as drake_lcmtypes

    from viewer_bridge.router.runner import RouteRunner
    from viewer_bridge.translators.base import Output
    from viewer_bridge.translators.registry import TRANSLATORS

    made: list[tuple[str, str]] = []
    published: list[bytes] = []

    def publisher_for(name: str, output: Output) -> CallPublisher:
        made.append((name, output.type.name))
        return CallPublisher(published.append, lambda: 0)  # nobody listens

    runner = RouteRunner(generic_route(lazy=True), lambda: TRANSLATORS.get("lcm_to_ros")({}), publisher_for)
    for channel in ("left-arm.status", "IIWA_STATUS"):
        match = re.fullmatch("(.*)", channel)
        assert match is not None
        runner.handle(Message(Received(channel, drake_lcmtypes.lcmt_iiwa_status().encode()), match))
    assert made == [
        ("/lcm/left_arm_status", "drake_lcm_msgs/msg/LcmtIiwaStatus"),
        ("/lcm/IIWA_STATUS", "drake_lcm_msgs/msg/LcmtIiwaStatus"),
    ]
    assert not published and runner.stats.idle_skipped == 2  # nothing translated: nobody listens


def budget_test_runner(policy: str, seconds: float, sent: list[bytes], budget: Any) -> Any:
    """A route of `policy` whose translation takes `seconds`, publishing into `sent`, on `budget`;
    its worker is not started: what is not translated inline waits in its mailbox."""
    from tests.router.test_commands import PassThrough
    from viewer_bridge.router.runner import RouteRunner

    class Timed(PassThrough):
        def translate(self, message: Received) -> Any:
            if seconds:
                time.sleep(seconds)
            return super().translate(message)

    route = Route.model_validate(
        {"name": policy, "source": {"transport": "lcm", "name": "X"}, "translator": "lcm_relay",
         "destination": {"transport": "lcm", "name": f"/{policy}"}, "rate": {"policy": policy}}
    )  # fmt: skip
    return RouteRunner(
        route, lambda: Timed({}), lambda name, output: CallPublisher(sent.append), inline=budget
    )


def fill(budget: Any) -> None:
    """The calling thread has translated inline for a second: past its budget's share."""
    now = time.perf_counter()
    budget.spent(now - 1.0, now)
    assert not budget.allows(time.perf_counter())


def test_a_quick_route_keeping_every_message_translates_inline_past_the_budget_and_fills_it() -> None:
    from viewer_bridge.router.flow import InlineBudget

    budget = InlineBudget(share=0.5, window_s=0.2)
    every: list[bytes] = []
    newest: list[bytes] = []
    quick = budget_test_runner("all", 0.0, every, budget)
    latest = budget_test_runner("latest", 0.0, newest, budget)
    fill(budget)
    quick.offer(Received("X", b"1", 0))  # past the budget, still inline
    latest.offer(Received("X", b"2", 0))  # past the budget: handed over, to be conflated
    assert (every, newest) == ([b"1"], []) and (len(quick.mailbox), len(latest.mailbox)) == (0, 1)


def test_a_slow_route_keeping_every_message_keeps_to_the_budget() -> None:
    """A translation over `QUICK_S` (1000-link markers) would hold the receiving thread from the
    quick routes beside it: past the budget it hands over, as a `latest` route does."""
    from viewer_bridge.router.flow import InlineBudget

    budget = InlineBudget(share=0.5, window_s=0.2)
    sent: list[bytes] = []
    slow = budget_test_runner("all", 0.15, sent, budget)  # 0.15 s: more than the budget's burst, too
    slow.offer(Received("X", b"1", 0))  # the budget allowed it: inline, and measured slow
    assert not budget.allows(time.perf_counter())  # its inline time counts in the thread's budget
    slow.offer(Received("X", b"2", 0))
    assert sent == [b"1"] and len(slow.mailbox) == 1


def test_one_slow_translation_does_not_make_a_quick_route_keep_to_the_budget() -> None:
    """The cost is the recent translations' mean: one outlier (a preempted thread) among quick
    translations leaves the route inline past the budget."""
    from viewer_bridge.router.flow import InlineBudget

    budget = InlineBudget(share=0.5, window_s=0.2)
    sent: list[bytes] = []
    route = budget_test_runner("all", 0.0, sent, budget)
    for index in range(50):
        route.offer(Received("X", bytes([index]), 0))
    route._cost_s += 0.0005  # one translation 5 ms long moves a mean of 10 by 0.5 ms: over QUICK_S
    fill(budget)
    for index in range(50, 110):  # handed over, until the mean of what the worker translates falls back
        route.offer(Received("X", bytes([index]), 0))
        while (message := route.mailbox.take()) is not None:
            route.handle(message)
    route.offer(Received("X", b"inline", 0))
    assert sent[-1] == b"inline" and len(sent) == 111 and not budget.allows(time.perf_counter())
