"""The QoS a ROS 2 subscription asks for when it follows its topic's publishers, and the words
the bridge says when a peer's QoS cannot match.

DDS matches a subscription to a publisher only when what the publisher offers is at least what the
subscription requests ("request vs offered"): a RELIABLE subscription gets nothing from a
BEST_EFFORT publisher, a TRANSIENT_LOCAL one nothing from a VOLATILE publisher. A subscription
that follows its publishers asks for what every one of them can give:

- reliability: best effort when any publisher is best effort, else reliable;
- durability: transient local when every publisher is transient local (then the publishers'
  history, up to the sum of their depths, arrives when it joins), else volatile;
- depth: the publishers' largest (the sum, for transient local), at most `max_depth`.

A policy the route's config sets stays as set (`Qos.follow` names the ones that follow). With no
publisher known yet, the route's own QoS is used until one appears. Rmw_zenoh carries the same
policies in its liveliness tokens, so the Zenoh transport follows the same table.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from viewer_bridge.transports.base import DEPTH, DURABILITY, RELIABILITY, Qos

DEFAULT_MAX_DEPTH = 100  # `ros.max_qos_depth`: what a followed subscription keeps at the most


@dataclass(frozen=True, slots=True)
class Offered:
    """What one publisher offers: reliable or best effort, transient local or volatile, its depth
    (0 for KEEP_ALL, which keeps what its resource limits allow)."""

    reliable: bool
    latched: bool
    depth: int


def followed(asked: Qos, publishers: Sequence[Offered], max_depth: int = DEFAULT_MAX_DEPTH) -> Qos:
    """The QoS a subscription asking `asked` takes from `publishers`: each policy in `asked.follow`
    from the publishers (the module's table), the others as asked."""
    if not publishers or not asked.follow:
        return asked
    reliable = all(p.reliable for p in publishers) if RELIABILITY in asked.follow else asked.reliable
    latched = all(p.latched for p in publishers) if DURABILITY in asked.follow else asked.latched
    depth = asked.depth
    if DEPTH in asked.follow:
        depths = [p.depth if p.depth > 0 else max_depth for p in publishers]
        depth = max(1, min(max_depth, sum(depths) if latched else max(depths)))
    return Qos(depth, reliable, latched, asked.follow, asked.told)


def same_profile(one: Qos, other: Qos) -> bool:
    """Whether two QoS make the same subscription (what a re-evaluation compares)."""
    return (one.depth, one.reliable, one.latched) == (other.depth, other.reliable, other.latched)


def describe(qos: Qos) -> str:
    """`reliable, transient_local, depth 5`: the words of the config's `qos:` keys."""
    reliability = "reliable" if qos.reliable else "best_effort"
    durability = "transient_local" if qos.latched else "volatile"
    return f"{reliability}, {durability}, depth {qos.depth}"


def incompatible_subscription(topic: str, policy: str, asked: Qos, publishers: Iterable[Offered]) -> str:
    """What the bridge says when a publisher on `topic` cannot give what its subscription asks
    (`policy`: the middleware's name of the last policy that failed)."""
    offered = sorted({describe(Qos(p.depth, p.reliable, p.latched)) for p in publishers})
    offers = f"; its publishers offer {' | '.join(offered)}" if offered else ""
    return (
        f"{topic}: a publisher offers less than the bridge's subscription asks ({describe(asked)}: "
        f"{policy.lower()} does not match){offers}. No message from that publisher arrives. Remove the "
        f"route's qos.{_config_key(policy)} so that it follows the publishers, or set it to what they offer"
    )


def incompatible_publication(topic: str, policy: str, offered: Qos) -> str:
    """What the bridge says when a subscriber on `topic` asks more than its publisher offers."""
    return (
        f"{topic}: a subscriber asks more than the bridge's publisher offers ({describe(offered)}: "
        f"{policy.lower()} does not match). That subscriber receives nothing; set the route's "
        f"qos.{_config_key(policy)} to what it asks, or subscribe with best_effort / volatile (as RViz "
        "and Foxglove can)"
    )


def _config_key(policy: str) -> str:
    """The config key of a DDS policy named by the middleware (`RELIABILITY` -> `reliability`)."""
    name = policy.lower()
    return name if name in (RELIABILITY, DURABILITY) else f"{RELIABILITY}/{DURABILITY}"
