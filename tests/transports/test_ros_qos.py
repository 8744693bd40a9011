"""The QoS a subscription takes from its topic's publishers: every row of the ROS 2 guide's table."""

from __future__ import annotations

import pytest

from viewer_bridge.transports.base import DEPTH, DURABILITY, RELIABILITY, Qos
from viewer_bridge.transports.ros_qos import (
    Offered,
    followed,
    incompatible_publication,
    incompatible_subscription,
    same_profile,
)

EVERY = frozenset({RELIABILITY, DURABILITY, DEPTH})
ASKED = Qos(10, True, False, EVERY)
RELIABLE = Offered(reliable=True, latched=False, depth=10)
BEST_EFFORT = Offered(reliable=False, latched=False, depth=5)
LATCHED = Offered(reliable=True, latched=True, depth=1)


@pytest.mark.parametrize(
    ("publishers", "reliable", "latched", "depth"),
    [
        ([RELIABLE], True, False, 10),
        ([BEST_EFFORT], False, False, 5),
        ([LATCHED], True, True, 1),
        ([RELIABLE, BEST_EFFORT], False, False, 10),  # any best effort: best effort; the largest depth
        ([LATCHED, RELIABLE], True, False, 10),  # not every one transient local: volatile
        ([LATCHED, Offered(True, True, 3)], True, True, 4),  # every one: transient local, the sum
        ([Offered(False, True, 2), LATCHED], False, True, 3),  # latched best effort
        ([Offered(True, False, 0)], True, False, 100),  # KEEP_ALL: the bound
        ([Offered(True, False, 5000)], True, False, 100),  # bounded
        ([Offered(True, True, 80), Offered(True, True, 80)], True, True, 100),  # the sum, bounded
    ],
)
def test_a_subscription_asks_what_every_publisher_gives(
    publishers: list[Offered], reliable: bool, latched: bool, depth: int
) -> None:
    qos = followed(ASKED, publishers, max_depth=100)
    assert (qos.reliable, qos.latched, qos.depth) == (reliable, latched, depth)
    assert qos.follow == EVERY  # it keeps following


def test_no_publisher_yet_keeps_the_routes_own_qos() -> None:
    assert followed(ASKED, []) is ASKED


def test_a_policy_the_config_sets_stays_as_set() -> None:
    reliable_only = Qos(10, True, False, frozenset({DURABILITY, DEPTH}))  # qos: {reliability: reliable}
    qos = followed(reliable_only, [BEST_EFFORT, Offered(False, False, 7)])
    assert (qos.reliable, qos.latched, qos.depth) == (True, False, 7)
    fixed = Qos(3, False, True)  # qos: {depth: 3, reliability: best_effort, durability: transient_local}
    assert followed(fixed, [RELIABLE]) is fixed


def test_profiles_compare_by_their_policies_alone() -> None:
    assert same_profile(Qos(5, False, False), Qos(5, False, False, EVERY, told=print))
    assert not same_profile(Qos(5, False, False), Qos(6, False, False))


def test_a_mismatch_is_said_with_the_policy_and_the_key_that_fixes_it() -> None:
    said = incompatible_subscription("/scan", "RELIABILITY", Qos(10, True, False), [BEST_EFFORT])
    assert said.startswith("/scan: ")  # the route counts and says it once per topic
    assert "reliability does not match" in said and "qos.reliability" in said
    assert "best_effort, volatile, depth 5" in said
    said = incompatible_publication("/drake/markers", "DURABILITY", Qos(10, True, False))
    assert "durability does not match" in said and "qos.durability" in said


def test_a_switch_passes_each_message_once_whichever_subscription_brings_it_first() -> None:
    from viewer_bridge.transports.ros2 import Switch

    def info(sent: int, sequence: int) -> dict[str, int]:
        return {"source_timestamp": sent, "publication_sequence_number": sequence}

    switch = Switch(covered=(1_000, 2_000), ends=float("inf"))  # earlier subscriptions: from 1,000 to 2,000
    # Live during the switch: both subscriptions bring it; the first copy passes, the second not.
    assert not switch.delivered(info(2_500, 7), history=False)
    assert switch.delivered(info(2_500, 7), history=True)
    # In flight at the switch: the new (transient-local) one's history copy comes first and is
    # dropped, the old one's live copy passes.
    assert switch.delivered(info(1_900, 6), history=True)
    assert not switch.delivered(info(1_900, 6), history=False)
    # Published before the first subscription existed: history nobody delivered, passed once.
    assert not switch.delivered(info(500, 1), history=True)
    assert switch.delivered(info(500, 1), history=True)
