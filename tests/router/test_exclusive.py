"""Exclusive destinations (`Translator.exclusive`, viewer_bridge/router/runner.py): each carries one
stream, the first to ask, across a router's routes; another is held and counted."""

from __future__ import annotations

from typing import Any, ClassVar

from tests.router.test_commands import PassThrough, Sent
from viewer_bridge.config.bridge import Route
from viewer_bridge.router.runner import Destinations, RouteRunner
from viewer_bridge.transports.base import Received


class Exclusive(PassThrough):
    exclusive: ClassVar[bool] = True


def runner(source: str, sent: Sent, destinations: Destinations | None) -> RouteRunner:
    route = Route.model_validate(
        {"name": f"topics_{source}", "source": {"transport": source, "name": "(/.*)"},
         "translator": "ros_topic_to_lcm", "destination": {"transport": "lcm", "name": "{1:lcm}"}}
    )  # fmt: skip
    return RouteRunner(route, lambda: Exclusive({}), sent.publisher, destinations=destinations)


def test_the_first_stream_keeps_a_destination_the_next_is_held_and_named() -> None:
    destinations, sent = Destinations(), Sent()
    dds, zenoh = runner("ros", sent, destinations), runner("zenoh", sent, destinations)
    dds.feed(Received("/dup", b"from dds"))
    zenoh.feed(Received("/dup", b"from zenoh"))
    zenoh.feed(Received("/dup", b"from zenoh"))
    dds.feed(Received("/dup", b"again"))
    zenoh.feed(Received("/other", b"other"))  # its own channel: carried
    assert [data for data, _ in sent.by_channel["dup"]] == [b"from dds", b"again"]
    assert [data for data, _ in sent.by_channel["other"]] == [b"other"]
    assert zenoh.snapshot()["held"] == {"/dup": {"channel_taken": 2}}
    assert dds.snapshot()["held"] == {}


def test_a_route_without_destinations_shares_nothing() -> None:
    sent: Any = Sent()
    first, second = runner("ros", sent, None), runner("zenoh", sent, None)
    first.feed(Received("/dup", b"a"))
    second.feed(Received("/dup", b"b"))
    assert [data for data, _ in sent.by_channel["dup"]] == [b"a", b"b"]
