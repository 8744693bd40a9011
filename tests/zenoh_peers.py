"""Zenoh peers for the tests: a router (in this process, or a process to kill), and an rmw_zenoh
node written from rmw_zenoh's design document and sources, not from the bridge's code.

Everything listens on 127.0.0.1 only, on a free port; nothing scouts by multicast.
`RmwZenohPeer` builds its keys, tokens and attachments here, by hand, from docs/PROTOCOLS.md
section 10: the tests compare what the bridge sends with what this peer expects.
"""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import xxhash
import zenoh
import zenoh.ext
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tests.conftest import read_line

STORE = get_typestore(Stores.ROS2_JAZZY)


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def free_lcm_url() -> str:
    """An LCM bus of its own: a UDP port no socket holds now (an ephemeral one: below the blocks
    tests/claims.py gives each test process for `lcm_url`), so no other test's traffic lands on it."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("0.0.0.0", 0))
        return f"udpm://239.255.76.67:{probe.getsockname()[1]}?ttl=0"


def stats_flags(path: Path) -> list[str]:
    """`viewer-bridge run`'s flags that have it write its stats to `path` twice a second."""
    return ["--stats-json", str(path), "--stats-period", "0.5"]


def written_stats(path: Path) -> dict[str, Any]:
    """The stats the bridge wrote last to `path` ({} before the first, or while it writes)."""
    try:
        return dict(json.loads(path.read_text()))
    except (OSError, ValueError):
        return {}


def stats_of(path: Path) -> dict[str, Any]:
    """Each route's stats the bridge wrote last to `path`, by name ({} before the first)."""
    return dict(written_stats(path).get("routes", {}))


def _config(mode: str, **keys: Any) -> zenoh.Config:
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("timestamping/enabled", "true")
    for key, value in keys.items():
        config.insert_json5(key.replace("__", "/"), json.dumps(value))
    return config


def router_config(port: int) -> zenoh.Config:
    return _config("router", listen__endpoints=[f"tcp/127.0.0.1:{port}"])


def client(endpoint: str) -> zenoh.Session:
    return zenoh.open(_config("client", connect__endpoints=[endpoint]))


class Router:
    """A Zenoh router in this process, on 127.0.0.1 and a free port."""

    def __init__(self, port: int | None = None) -> None:
        self.port = port or free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        self.session = zenoh.open(router_config(self.port))

    def close(self) -> None:
        self.session.close()  # type: ignore[no-untyped-call]


_ROUTER_SCRIPT = """
import signal, sys, zenoh
from tests.zenoh_peers import router_config
session = zenoh.open(router_config(int(sys.argv[1])))
print("router up", flush=True)
signal.sigwait([signal.SIGTERM, signal.SIGINT])
"""


class RouterProcess:
    """A Zenoh router in a process of its own, to be killed (SIGKILL) and started again on its port."""

    def __init__(self) -> None:
        self.port = free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        self.process: subprocess.Popen[str] | None = None

    def start(self) -> float:
        """Start it; returns the monotonic time at which it said it was up."""
        self.process = subprocess.Popen(
            [sys.executable, "-c", _ROUTER_SCRIPT, str(self.port)], stdout=subprocess.PIPE, text=True
        )
        assert self.process.stdout is not None
        assert read_line(self.process.stdout, "'router up' from the router process").strip() == "router up"
        return time.monotonic()

    def kill(self) -> None:
        if self.process is not None:
            self.process.kill()
            self.process.wait(timeout=30)


# --- an rmw_zenoh node, from the design document -------------------------------------------------------


def type_hash(typename: str) -> str:
    return STORE.hash_rihs01(typename)  # type: ignore[no-any-return]


def rihs01(typename: str, definitions: dict[str, str]) -> str:
    """The RIHS01 hash of a type that is not one of Jazzy's (an LCM type's mapping), computed by
    rosbags from the `.msg` definitions ("pkg/msg/Name" -> text) of it and the types it uses."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for name, text in definitions.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store.hash_rihs01(typename)  # type: ignore[no-any-return]


def dds_name(typename: str) -> str:
    package, _, name = typename.split("/")
    return f"{package}::msg::dds_::{name}_"


def data_key(domain: int, topic: str, typename: str, hash_: str | None = None) -> str:
    return f"{domain}/{topic.strip('/')}/{dds_name(typename)}/{hash_ or type_hash(typename)}"


def publisher_token(
    domain: int,
    zid: str,
    entity: int,
    node: str,
    topic: str,
    typename: str,
    qos: str,
    hash_: str | None = None,
) -> str:
    """`@ros2_lv/<domain>/<zid>/<node id>/<entity id>/MP/<enclave>/<namespace>/<node>/<topic>/<type>/<hash>/<qos>`
    with `/` as `%` inside a part (the root namespace and enclave `/`: `%`); the hash is Jazzy's
    type's unless given."""
    mangled = topic.replace("/", "%")
    hashed = hash_ or type_hash(typename)
    return f"@ros2_lv/{domain}/{zid}/0/{entity}/MP/%/%/{node}/{mangled}/{dds_name(typename)}/{hashed}/{qos}"


@dataclass
class Arrival:
    key: str
    payload: bytes
    attachment: bytes | None
    at_ns: int


class RmwZenohPeer:
    """One session acting as an rmw_zenoh node: subscribes to data keys (with history when
    latched, as rmw_zenoh's TRANSIENT_LOCAL subscriptions do), reads the graph's tokens, and
    publishes with its own token and attachments."""

    def __init__(self, endpoint: str, domain: int, node: str = "probe") -> None:
        self.session = client(endpoint)
        self.zid = str(self.session.zid())
        self.domain = domain
        self.node = node
        self.arrivals: dict[str, list[Arrival]] = {}
        self._held: list[Any] = [
            self.session.liveliness().declare_token(f"@ros2_lv/{domain}/{self.zid}/0/0/NN/%/%/{node}")
        ]
        self._lock = threading.Lock()
        self._sequence = 0

    def subscribe(
        self, topic: str, typename: str, latched: bool = False, depth: int = 10, type_hash: str | None = None
    ) -> list[Arrival]:
        """What arrives on the topic's data key (`type_hash`: for a type not in Jazzy)."""
        arrivals = self.arrivals.setdefault(topic, [])

        def keep(sample: zenoh.Sample) -> None:
            attachment = sample.attachment
            with self._lock:
                arrivals.append(
                    Arrival(str(sample.key_expr), sample.payload.to_bytes(),
                            None if attachment is None else attachment.to_bytes(), time.time_ns())
                )  # fmt: skip

        key = data_key(self.domain, topic, typename, type_hash)
        if latched:
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=depth)
            self._held.append(zenoh.ext.declare_advanced_subscriber(self.session, key, keep, history=history))
        else:
            self._held.append(self.session.declare_subscriber(key, keep))
        return arrivals

    def subscribed(self, topic: str) -> bool:
        """Whether some node announces a subscriber (an MS token) on `topic`."""
        mangled = topic.replace("/", "%")
        return any("/MS/" in token and f"/{mangled}/" in token for token in self.tokens())

    def tokens(self) -> list[str]:
        replies = self.session.liveliness().get(f"@ros2_lv/{self.domain}/**")
        return [str(reply.ok.key_expr) for reply in replies if reply.ok is not None]

    def publisher(
        self,
        topic: str,
        typename: str,
        entity: int = 1,
        type_hash: str | None = None,
        *,
        depth: int = 10,
        best_effort: bool = False,
        latched: bool = False,
    ) -> Callable[..., None]:
        """`publish(cdr, attachment=None)`: on the topic's key, with this node's MP token (the
        liveliness token rmw_zenoh declares for a publisher, which a bridge finds it by); the
        attachment is rmw_zenoh's unless one is given. `type_hash`: for a type not in Jazzy.

        As rmw_zenoh 0.2.3 and later write the QoS in the token (reliability, durability,
        history,depth, each empty when it is rmw_zenoh's default: reliable, volatile, keep last,
        depth 42; BEST_EFFORT is 2, TRANSIENT_LOCAL 1), and as they publish TRANSIENT_LOCAL: an
        advanced publisher with a cache of `depth` samples that announces itself, which a late
        subscriber with history queries."""
        reliability, durability = ("2" if best_effort else ""), ("1" if latched else "")
        qos = f"{reliability}:{durability}:,{depth}:,:,:,,"
        token = publisher_token(self.domain, self.zid, entity, self.node, topic, typename, qos, type_hash)
        self._held.append(self.session.liveliness().declare_token(token))
        digest = xxhash.xxh3_128_intdigest(token.encode())
        gid = struct.pack("<QQ", digest & (2**64 - 1), digest >> 64)
        key = data_key(self.domain, topic, typename, type_hash)
        kind = zenoh.Reliability.BEST_EFFORT if best_effort else zenoh.Reliability.RELIABLE
        put: Any = (
            zenoh.ext.declare_advanced_publisher(
                self.session,
                key,
                reliability=kind,
                cache=zenoh.ext.CacheConfig(depth),
                publisher_detection=True,
            )
            if latched
            else self.session.declare_publisher(key, reliability=kind)
        )
        self._held.append(put)

        def publish(cdr: bytes, attachment: bytes | None = None) -> None:
            self._sequence += 1
            stamp = struct.pack("<qqB", self._sequence, time.time_ns(), 16) + gid
            put.put(cdr, attachment=stamp if attachment is None else attachment)

        return publish

    def close(self) -> None:
        self._held.clear()
        self.session.close()  # type: ignore[no-untyped-call]


def decode(arrival: Arrival, typename: str) -> Any:
    return STORE.deserialize_cdr(arrival.payload, typename)
