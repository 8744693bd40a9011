"""A route's express path (viewer_bridge/router/runner.py `RouteRunner.express`): the messages it
carries are published and counted as the full path's, one in `EXPRESS_SAMPLE` is left to the full
path for the stats, and it declines whenever the full path must decide (the route busy, a lazy
route's listeners gone, a lane let go, a type not seen yet). And the LCM transport that uses it."""

from __future__ import annotations

import time
from typing import Any

import drake as drake_lcmtypes

from tests.router.test_runner import generic_route
from viewer_bridge.config.bridge import Route
from viewer_bridge.router.flow import InlineBudget
from viewer_bridge.router.runner import EXPRESS_MAX_BYTES, EXPRESS_SAMPLE, RouteRunner
from viewer_bridge.translators.base import Output, Translator
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import CallPublisher, ClosingPublisher, Qos, Received
from viewer_bridge.transports.lcm import LcmSettings, LcmTransport


def relay_runner(sent: list[bytes], plain: bool = True, **route: Any) -> RouteRunner:
    config = Route.model_validate(
        {"name": "relay", "source": {"transport": "lcm", "name": "(X.*)"}, "translator": "lcm_relay",
         "destination": {"transport": "zenoh", "name": "{1}"}, "rate": {"policy": "all"}, **route}
    )  # fmt: skip
    return RouteRunner(
        config,
        lambda: TRANSLATORS.get("lcm_relay")({}),
        lambda name, output: ClosingPublisher(sent.append, close=lambda: None),
        InlineBudget(),
        plain_destination=plain,
    )


def carry(runner: RouteRunner, channel: str, data: bytes) -> bool:
    """As the LCM transport does: the express path if there is one and it takes the message, else
    the full path (after which the express path is asked for again); whether it was express."""
    express = runner.express(channel)
    if express is not None and express(data):
        return True
    runner.offer(Received(channel, data))
    return False


def test_the_express_path_carries_and_counts_what_the_full_path_would_and_leaves_it_a_sample() -> None:
    sent: list[bytes] = []
    runner = relay_runner(sent)
    assert runner.express("X1") is None  # no lane yet: its first message takes the full path
    messages = [bytes([index % 256]) * (1 + index % 7) for index in range(10 * EXPRESS_SAMPLE)]
    expressed = sum(carry(runner, "X1", data) for data in messages)
    assert sent == messages  # every message, in order
    stats = runner.stats
    assert (stats.messages_in, stats.messages_out) == (len(messages), len(messages))
    assert stats.bytes_in == stats.bytes_out == sum(map(len, messages))
    full = len(messages) - expressed  # the first, and one in EXPRESS_SAMPLE after it
    assert 10 <= full <= 11 and len(stats.translate_ms) == len(stats.latency_ms) == full


def test_no_express_path_where_the_full_path_must_decide() -> None:
    sent: list[bytes] = []
    assert relay_runner(sent, plain=False).express("X1") is None  # a file stamps its message's time
    assert relay_runner(sent, rate={"policy": "all", "max_hz": 10}).express("X1") is None
    runner = relay_runner(sent)
    carry(runner, "X1", b"first")
    express = runner.express("X1")
    assert express is not None and runner.express("Y") is None  # not the route's channel
    with runner._turn:  # its worker translates: the message waits its turn in the mailbox
        assert not express(b"busy")
        runner.offer(Received("X1", b"busy"))
    assert not express(b"behind")  # one waits in the mailbox: the next goes behind it
    runner.offer(Received("X1", b"behind"))
    while (message := runner.mailbox.take()) is not None:  # the worker's turn (not running here)
        runner.handle(message)
    assert express(b"after") and sent == [b"first", b"busy", b"behind", b"after"]
    assert not express(bytes(EXPRESS_MAX_BYTES + 1))  # a large one: the full path times it


def test_a_stream_let_go_has_no_express_path() -> None:
    sent: list[bytes] = []
    now = [0.0]
    config = Route.model_validate(
        {"name": "relay", "source": {"transport": "lcm", "name": "(X.*)"}, "translator": "lcm_relay",
         "destination": {"transport": "zenoh", "name": "{1}"}, "rate": {"policy": "all"}, "max_streams": 1,
         "stream_idle_s": 1.0}
    )  # fmt: skip
    runner = RouteRunner(
        config,
        lambda: TRANSLATORS.get("lcm_relay")({}),
        lambda name, output: ClosingPublisher(sent.append, close=lambda: None),
        InlineBudget(),
        clock=lambda: now[0],
        plain_destination=True,
    )
    carry(runner, "X1", b"1")
    express = runner.express("X1")
    assert express is not None and express(b"2")
    now[0] = 5.0
    carry(runner, "X2", b"3")  # held: X1 was used since the last look (which dates it now)
    now[0] = 10.0
    carry(runner, "X2", b"4")  # X1 has been quiet past stream_idle_s: its lane goes to X2
    assert not express(b"5")  # X1's old lane carries no more
    assert runner.express("X1") is None and sent == [b"1", b"2", b"4"]


def test_a_lazy_route_with_nobody_listening_any_more_takes_the_full_path_and_skips() -> None:
    listeners = [1]
    published: list[bytes] = []

    def publisher_for(name: str, output: Output) -> CallPublisher:
        return CallPublisher(published.append, lambda: listeners[0])

    runner = RouteRunner(
        generic_route(lazy=True),
        lambda: TRANSLATORS.get("lcm_to_ros")({}),
        publisher_for,
        InlineBudget(),
        plain_destination=True,
    )
    data = drake_lcmtypes.lcmt_iiwa_status().encode()
    carry(runner, "IIWA_STATUS", data)
    assert carry(runner, "IIWA_STATUS", data)  # a known type, someone listens: express
    assert published[0] == published[1]  # the same CDR as the full path's
    listeners[0] = 0
    deadline = time.monotonic() + 30
    while runner.stats.idle_skipped == 0 and time.monotonic() < deadline:  # asked again within 0.25 s
        carry(runner, "IIWA_STATUS", data)
        time.sleep(0.01)
    assert runner.stats.idle_skipped == 1
    assert not carry(runner, "IIWA_STATUS", data) and runner.stats.idle_skipped == 2
    other = drake_lcmtypes.lcmt_iiwa_command().encode()
    listeners[0] = 1
    time.sleep(0.3)
    assert not carry(runner, "IIWA_STATUS", other)  # a type not seen yet: the full path adds its output


def test_the_lcm_transport_carries_a_channel_on_its_routes_express_path() -> None:
    """A live bus (memq: in this process): each message of a channel whose one route offers an
    express path is carried by it, but the sampled ones; the channel's other routes' would not be."""
    transport = LcmTransport(LcmSettings(url="memq://"))
    sent: list[bytes] = []
    runner = relay_runner(sent)
    both: list[Received] = []
    any_lcm = TRANSLATORS.get("lcm_relay").reads[0]
    transport.subscribe("(X.*)", any_lcm, Qos(), runner.offer)
    transport.offer_express(runner.offer, runner.express)
    transport.subscribe("Y", any_lcm, Qos(), both.append)
    transport.start()
    try:
        messages = [bytes([index % 256]) * 8 for index in range(4 * EXPRESS_SAMPLE)]
        for data in messages:
            transport.bus.publish("X1", data)
            transport.bus.publish("Y", data)
        deadline = time.monotonic() + 30
        while (len(sent) < len(messages) or len(both) < len(messages)) and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        transport.close()
    assert sent == messages and [received.data for received in both] == messages
    assert runner.stats.messages_in == len(messages)
    assert len(runner.stats.translate_ms) <= 5  # the first and the samples timed: the rest express


def test_a_channel_of_one_type_is_transcoded_directly_and_another_type_takes_the_full_path() -> None:
    """`lcm_to_ros` on a channel of one type: the express path calls its transcoder alone
    (`Translator.direct`), and a message it cannot make (another fingerprint, the same size: the
    kept layout compares it) goes to the full path, which holds it as an unknown type."""
    published: list[bytes] = []
    made: list[Translator] = []

    def lcm_to_ros() -> Translator:
        made.append(TRANSLATORS.get("lcm_to_ros")({}))
        return made[-1]

    runner = RouteRunner(
        generic_route(lazy=False),
        lcm_to_ros,
        lambda name, output: CallPublisher(published.append, lambda: 1),
        InlineBudget(),
        plain_destination=True,
    )
    data = drake_lcmtypes.lcmt_iiwa_status().encode()
    carry(runner, "IIWA_STATUS", data)
    [translator] = made  # the route's one translator, its channel's
    index, make = translator.direct() or (None, None)
    assert index == 0 and make is not None and make(data) == published[0]
    assert carry(runner, "IIWA_STATUS", data) and published[1] == published[0]  # express, same CDR
    unknown = bytes(8) + data[8:]  # a fingerprint no known type has
    assert not carry(runner, "IIWA_STATUS", unknown)
    assert runner.stats.held == {"IIWA_STATUS": {"unknown_type": 1}} and len(published) == 2
    assert carry(runner, "IIWA_STATUS", data) and len(published) == 3


def test_behind_the_loop_guard_only_the_channels_the_bridge_may_write_lose_the_express_path() -> None:
    """`router.unwritten`: the default config (its way back writes what `commands.allow` allows,
    nothing unless told) guards no channel, so each route reading LCM keeps its express path; with
    `--allow-commands IIWA_COMMAND` that channel alone is read by the guard. A route writing LCM
    under a template may write any channel (every one guarded), one with a plain name that name."""
    from viewer_bridge.config.bridge import BridgeConfig, load_config
    from viewer_bridge.router.router import unwritten

    def express_for(channel: str) -> Any:
        return f"express {channel}"

    default = load_config(None)
    assert any(route.destination.transport == "lcm" for route in default.routes)  # its way back
    assert unwritten(default, "lcm", express_for)("IIWA_COMMAND") == "express IIWA_COMMAND"
    allowing = unwritten(default.allowing_commands(["IIWA_COMMAND"]), "lcm", express_for)
    assert allowing("IIWA_COMMAND") is None and allowing("IIWA_STATUS") == "express IIWA_STATUS"

    def writing(name: str) -> BridgeConfig:
        return BridgeConfig.model_validate(
            {"lcm": {"url": "memq://"}, "routes": [
                {"name": "out", "source": {"transport": "lcm", "name": "(X.*)"}, "translator": "lcm_relay",
                 "destination": {"transport": "lcm", "name": name}}]}
        )  # fmt: skip

    assert unwritten(writing("{1}_COPY"), "lcm", express_for)("Y") is None
    plain = unwritten(writing("X_COPY"), "lcm", express_for)
    assert plain("X_COPY") is None and plain("X1") == "express X1"
    assert unwritten(writing("X_COPY"), "zenoh", express_for)("X_COPY") == "express X_COPY"
