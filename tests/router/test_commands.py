"""Routes that write commands (viewer_bridge/transports/command_policy.py, viewer_bridge/router/runner.py): only the
channels the config allows, only fresh messages, and a bounded number of streams per route."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any, ClassVar

import pytest

from viewer_bridge.config.bridge import Route
from viewer_bridge.errors import BridgeError, ConfigError, Held
from viewer_bridge.router.runner import MAX_HELD_CHANNELS, OTHER_CHANNELS, RouteRunner
from viewer_bridge.translators.base import Output, Outputs, Translator
from viewer_bridge.transports.base import (
    LCM,
    CallPublisher,
    ClosingPublisher,
    MessageType,
    Publisher,
    Received,
)
from viewer_bridge.transports.command_policy import CommandPolicy

WAIT = 60.0


class PassThrough(Translator):
    """Sends each message's bytes as they are."""

    reads = (MessageType("*", LCM),)
    outputs: ClassVar[tuple[Output, ...]] = (Output("", MessageType("*", LCM)),)

    def translate(self, message: Received) -> Outputs:
        return [(0, message.data)]


class PassCommands(PassThrough):
    """A command writer (the way back, minus the codec)."""

    commands = True


def command_route(**fields: Any) -> Route:
    return Route.model_validate(
        {"name": "lcm_in", "source": {"transport": "ros", "name": "/lcm_in/(.*)"}, "translator": "ros_to_lcm",
         "destination": {"transport": "lcm", "name": "{1}"}} | fields
    )  # fmt: skip


class Sent:
    """What the route published, by channel, with when it was published."""

    def __init__(self) -> None:
        self.by_channel: dict[str, list[tuple[bytes, int]]] = {}

    def publisher(self, name: str, output: Output) -> Publisher:
        def publish(data: bytes) -> None:
            self.by_channel.setdefault(name, []).append((data, time.time_ns() // 1000))

        return CallPublisher(publish)


def runner_for(
    policy: CommandPolicy, route: Route | None = None, publish: Callable[[bytes], None] | None = None
) -> tuple[RouteRunner, Sent, list[BridgeError]]:
    """A command route's runner; what it sends goes to `Sent`, or to `publish` when given."""
    sent, told = Sent(), []
    publisher_for = sent.publisher if publish is None else lambda name, output: CallPublisher(publish)
    runner = RouteRunner(
        route or command_route(), lambda: PassCommands({}), publisher_for,
        rejected=lambda message, error: told.append(error), commands=policy,
    )  # fmt: skip
    return runner, sent, told


def test_only_allowed_channels_are_written_and_each_refusal_is_counted_and_answered() -> None:
    runner, sent, told = runner_for(CommandPolicy(allow=("WSG_COMMAND",)))
    runner.feed(Received("/lcm_in/WSG_COMMAND", b"grip"))
    runner.feed(Received("/lcm_in/IIWA_COMMAND", b"move"))
    runner.feed(Received("/lcm_in/IIWA_COMMAND", b"move"))
    assert sent.by_channel.keys() == {"WSG_COMMAND"}
    assert runner.snapshot()["held"] == {"/lcm_in/IIWA_COMMAND": {"not_allowed": 2}}
    assert len(told) == 2 and all(isinstance(error, Held) for error in told)
    assert "IIWA_COMMAND may not be commanded (allowed: WSG_COMMAND)" in str(told[0])
    assert "--allow-commands 'IIWA_COMMAND'" in str(told[0])


def test_with_nothing_allowed_nothing_is_written() -> None:
    runner, sent, told = runner_for(CommandPolicy())
    for channel in ("IIWA_COMMAND", "WSG_COMMAND", "ANYTHING"):
        runner.feed(Received(f"/lcm_in/{channel}", b"x"))
    assert not sent.by_channel and len(told) == 3
    assert "(none is allowed)" in str(told[0])


def test_a_pattern_matches_the_whole_channel_name() -> None:
    policy = CommandPolicy(allow=("IIWA_COMMAND|WSG_.*",))
    assert policy.allows("IIWA_COMMAND") and policy.allows("WSG_COMMAND")
    assert not policy.allows("IIWA_COMMAND_2") and not policy.allows("MY_IIWA_COMMAND")


def test_a_pattern_that_is_no_regular_expression_is_a_config_error(tmp_path: Any) -> None:
    from viewer_bridge.config.bridge import load_config

    path = tmp_path / "bridge.yaml"
    path.write_text("commands:\n  allow: ['IIWA_(']\nroutes: []\n")
    with pytest.raises(ConfigError, match=r"bridge.yaml:2: commands.allow.*not a regular expression"):
        load_config(path)


def stalled(
    route: Route, policy: CommandPolicy, stall_s: float, send_for_s: float, count: int = 100
) -> tuple[RouteRunner, list[int], int]:
    """The route's publisher stalls for `stall_s` on its first message (as a blocked socket or a
    busy core would), while `count` commands arrive over the first `send_for_s` seconds. Returns
    the runner, the receive times of what was sent after the stall, and when the stall ended."""
    release, stalling = threading.Event(), threading.Event()
    published: list[int] = []

    def publish(data: bytes) -> None:
        if not stalling.is_set():
            stalling.set()
            release.wait(WAIT)
        published.append(int(data))

    runner, _, _ = runner_for(policy, route, publish)
    runner.start()
    try:
        # stalls its thread
        runner.offer(Received("/lcm_in/IIWA_COMMAND", str(time.time_ns() // 1000).encode()))
        assert stalling.wait(WAIT)
        for _ in range(count):
            runner.offer(Received("/lcm_in/IIWA_COMMAND", str(time.time_ns() // 1000).encode()))
            time.sleep(send_for_s / count)
        time.sleep(max(0.0, stall_s - send_for_s))
        resumed_us = time.time_ns() // 1000
        release.set()
        deadline = time.monotonic() + WAIT
        while len(runner.mailbox) and time.monotonic() < deadline:  # what waited is taken (sent or dropped)
            time.sleep(0.01)
        with runner._turn:  # the worker takes a message under its turn and keeps it until handled
            pass
    finally:
        runner.stop()
        runner.join(timeout=5)
    return runner, published[1:], resumed_us


def test_a_stalled_command_route_sends_at_most_one_afterwards_and_nothing_stale() -> None:
    """The stall in the receiving thread: 100 commands meanwhile, over the whole 2 s stall."""
    route = command_route(rate={"policy": "latest"})
    policy = CommandPolicy(allow=(".*",), max_age_ms=200)
    runner, after, resumed_us = stalled(route, policy, stall_s=2.0, send_for_s=2.0)
    assert len(after) <= 1, after
    for received_us in after:
        # at most the age limit when taken (+ the handover)
        assert resumed_us - received_us <= 200_000 + 100_000
    assert runner.mailbox.dropped == 99  # superseded while the route stalled: the newest waited


def test_commands_that_went_stale_during_a_stall_are_never_sent() -> None:
    """100 commands in the first half second of a 2 s stall: all older than 200 ms when it ends."""
    route = command_route(rate={"policy": "latest"})
    policy = CommandPolicy(allow=(".*",), max_age_ms=200)
    runner, after, _ = stalled(route, policy, stall_s=2.0, send_for_s=0.5)
    assert after == []
    assert runner.snapshot()["held"]["/lcm_in/IIWA_COMMAND"]["stale"] == 1  # the newest, taken and dropped


def test_a_route_gives_at_most_max_streams_channels_their_own_publisher() -> None:
    """A bus with 10,000 channel names: 1,000 get a lane and a publisher, the rest are held and
    counted, and the per-channel counts stay bounded too."""
    made: list[str] = []

    def publisher(name: str, output: Output) -> Publisher:
        made.append(name)
        return CallPublisher(lambda data: None)

    route = Route.model_validate(
        {"name": "bus", "source": {"transport": "lcm", "name": "(.*)"}, "translator": "lcm_to_ros",
         "destination": {"transport": "ros", "name": "/lcm/{1:topic}"}}
    )  # fmt: skip
    runner = RouteRunner(route, lambda: PassThrough({}), publisher)
    for index in range(10_000):
        runner.feed(Received(f"CHANNEL_{index}", b"x"))
    assert len(made) == route.max_streams == 1000
    held = runner.snapshot()["held"]
    assert len(held) == MAX_HELD_CHANNELS + 1 and held[OTHER_CHANNELS] == {
        "too_many_streams": 9000 - MAX_HELD_CHANNELS
    }
    assert sum(kinds["too_many_streams"] for kinds in held.values()) == 9000


def test_streams_quiet_for_stream_idle_s_give_their_lanes_to_a_channel_that_comes_later() -> None:
    """6,000 junk channel names take the route's 1,000 lanes; once they have been quiet for
    `stream_idle_s` (30 s, on the route's clock), the real IIWA_STATUS that comes later gets a lane
    and a publisher, the quiet streams' publishers are closed, a stream still sending keeps its lane,
    and the route never holds more than `max_streams` lanes or publishers."""
    made: list[str] = []
    closed: list[str] = []

    def publisher(name: str, output: Output) -> Publisher:
        made.append(name)
        return ClosingPublisher(lambda data: None, close=lambda: closed.append(name))

    route = Route.model_validate(
        {"name": "bus", "source": {"transport": "lcm", "name": "(.*)"}, "translator": "lcm_to_ros",
         "destination": {"transport": "ros", "name": "/lcm/{1:topic}"}}
    )  # fmt: skip
    assert route.stream_idle_s == 30.0
    now = [0.0]
    translators: list[PassThrough] = []  # one per stream the route opens

    def pass_through() -> PassThrough:
        translators.append(PassThrough({}))
        return translators[-1]

    runner = RouteRunner(route, pass_through, publisher, clock=lambda: now[0])

    def too_many() -> int:
        return sum(kinds.get("too_many_streams", 0) for kinds in runner.snapshot()["held"].values())

    for index in range(6000):
        runner.feed(Received(f"JUNK_{index}", b"x"))
    now[0] = 10.0
    runner.feed(Received("IIWA_STATUS", b"real"))  # none quiet for 30 s yet: held
    assert too_many() == 5001 and "/lcm/IIWA_STATUS" not in made
    now[0] = 20.0
    runner.feed(Received("JUNK_0", b"x"))  # still sending: keeps its lane
    now[0] = 31.0
    runner.feed(Received("IIWA_STATUS", b"real"))
    assert made[-1] == "/lcm/IIWA_STATUS" and too_many() == 5001
    assert len(closed) == 999 and "/lcm/JUNK_0" not in closed
    assert runner.snapshot()["streams_reclaimed"] == 999 and runner.stats.messages_out == 1002
    # A second flood takes what is free, and no more: the bound holds
    for index in range(6000, 12_000):
        runner.feed(Received(f"JUNK_{index}", b"x"))
    now[0] = 32.0
    runner.feed(Received("IIWA_STATUS", b"real"))
    assert runner.stats.messages_out == 1002 + 998 + 1
    assert len(made) - len(closed) == route.max_streams  # publishers open
    assert len(translators) - runner.snapshot()["streams_reclaimed"] == route.max_streams  # streams open
    # Publishers that cannot free their transport's state (Zenoh's, gz's) keep their lanes
    kept = RouteRunner(route.model_copy(update={"max_streams": 2}), lambda: PassThrough({}),
                       lambda name, output: CallPublisher(lambda data: None), clock=lambda: now[0])  # fmt: skip
    for channel in ("A", "B"):
        kept.feed(Received(channel, b"x"))
    now[0] = 100.0
    kept.feed(Received("IIWA_STATUS", b"real"))
    assert kept.stats.messages_out == 2 and kept.stats.streams_reclaimed == 0


def test_stream_idle_s_is_a_route_setting() -> None:
    route = Route.model_validate(
        {"name": "bus", "source": {"transport": "lcm", "name": "(.*)"}, "translator": "lcm_to_ros",
         "destination": {"transport": "ros", "name": "/lcm/{1:topic}"}, "stream_idle_s": 0.5}
    )  # fmt: skip
    assert route.stream_idle_s == 0.5
    with pytest.raises(ValueError, match="stream_idle_s"):
        Route.model_validate(route.model_dump() | {"stream_idle_s": 0})


def test_a_second_channel_that_makes_a_token_is_refused_and_only_the_allow_list_maps_tokens_back(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """`/lcm/{1:topic}` made tokens of the channels seen (`1ARM` -> `n1ARM`, `a.b` -> `a_b`; `a-b`,
    whose token `a.b` has, is refused, never merged into `/lcm/a_b`); `/lcm_in/{1:channel}` maps a
    name back by the allow-list alone: the name itself when allowed, else the channel the list names
    literally with that token, whatever channels the bus has shown."""
    from viewer_bridge.transports.ros_names import ChannelNames

    names = ChannelNames()
    made: list[str] = []
    outward = Route.model_validate(
        {"name": "bus", "source": {"transport": "lcm", "name": "(.*)"}, "translator": "lcm_to_ros",
         "destination": {"transport": "ros", "name": "/lcm/{1:topic}"}}
    )  # fmt: skip
    out = RouteRunner(outward, lambda: PassThrough({}), lambda name, output: (made.append(name), CallPublisher(print))[1],
                      names=names)  # fmt: skip
    for channel in ("1ARM", "a.b", "a-b", "IIWA_STATUS", "IIWA-COMMAND"):
        out.feed(Received(channel, b"x"))
    out.feed(Received("a-b", b"y"))  # counted each time, said once
    assert made == ["/lcm/n1ARM", "/lcm/a_b", "/lcm/IIWA_STATUS", "/lcm/IIWA_COMMAND"]
    assert out.stats.held == {"a-b": {"name_collision": 2}}
    said = [record.getMessage() for record in caplog.records if "name_collision" in record.getMessage()]
    assert said == [
        "route bus: a-b: LCM channels a.b and a-b both become the ROS name a_b: a-b is not carried "
        "(a.b, seen first, keeps it; rename one of them) (name_collision; counted, not said again)"
    ]

    sent, told = Sent(), []
    back = RouteRunner(
        command_route(destination={"transport": "lcm", "name": "{1:channel}"}), lambda: PassCommands({}),
        sent.publisher, rejected=lambda message, error: told.append(error),
        commands=CommandPolicy(allow=("1ARM", r"a\.b", "IIWA_.*")), names=names,
    )  # fmt: skip
    for topic in ("/lcm_in/n1ARM", "/lcm_in/a_b", "/lcm_in/IIWA_COMMAND", "/lcm_in/a_c"):
        back.feed(Received(topic, b"go"))
    # IIWA_COMMAND is allowed as it is: IIWA-COMMAND, seen on the bus, takes nothing
    assert sorted(sent.by_channel) == ["1ARM", "IIWA_COMMAND", "a.b"]
    assert [str(error) for error in told] == [
        CommandPolicy(allow=("1ARM", r"a\.b", "IIWA_.*")).refusal("a_c")
    ]


def test_the_allow_list_is_the_table_of_command_names() -> None:
    """Literal names (plain characters, escaped punctuation, `|` between them) give their tokens to
    their channels; a name the list allows as it is keeps it; two allowed channels on one name are
    said."""
    from viewer_bridge.transports.command_policy import literal_channels

    assert literal_channels(r"IIWA-COMMAND|WSG\.COMMAND") == ["IIWA-COMMAND", "WSG.COMMAND"]
    assert literal_channels(r"IIWA\ COMMAND") == ["IIWA COMMAND"]
    for regex in ("IIWA_.*", "IIWA.COMMAND", "(A|B)", r"\d+", "[AB]", "A\\", "^A$"):
        assert literal_channels(regex) == [], regex
    policy = CommandPolicy(allow=("IIWA_COMMAND", "IIWA-COMMAND", "a.b", "1ARM", r"x\-y", r"x\.y"))
    assert policy.channel("IIWA_COMMAND") == "IIWA_COMMAND"
    assert policy.channel("n1ARM") == "1ARM"
    assert policy.channel("a_b") == "a_b"  # a.b is a regex: it allows a_b itself
    assert policy.channel("x_y") == "x-y"  # the first named keeps it
    assert policy.channel("WSG_COMMAND") == "WSG_COMMAND"  # not allowed: refused under its own name
    assert policy.collisions() == [
        "allowed LCM channels IIWA_COMMAND and IIWA-COMMAND would both be commanded as /lcm_in/IIWA_COMMAND: "
        "it commands IIWA_COMMAND; IIWA-COMMAND cannot be commanded (rename one)",
        "allowed LCM channels x-y and x.y would both be commanded as /lcm_in/x_y: it commands x-y; x.y "
        "cannot be commanded (rename one)",
    ]
    assert CommandPolicy(allow=("IIWA_COMMAND|WSG_COMMAND", "IIWA_COMMAND")).collisions() == []
