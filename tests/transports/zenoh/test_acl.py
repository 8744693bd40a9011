"""The guide's access control (docs/zenoh.md, "Who may command your robot over Zenoh") in a real
Zenoh router in this process: its config, logins and the bridge's config file are read from the
guide's code blocks, so the tests fail when the guide's text stops working.

Only the router's listening endpoint (127.0.0.1 and a free port) and the dictionary's path are
changed from the guide's; every client connects there. Nothing waits a fixed time: a message that
must not arrive is judged once a later one from the same session, on an open key, has arrived
(Zenoh keeps one session's messages in order through the router to one subscriber).
"""

from __future__ import annotations

import json
import os
import re
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import zenoh

from tests.peers import wait_for
from tests.zenoh_peers import data_key, free_port
from viewer_bridge.transports.zenoh import session as bridge_session

GUIDE = Path(__file__).parents[3] / "docs" / "zenoh.md"
SECTION = "## Who may command your robot over Zenoh"
TYPE = "geometry_msgs/msg/PoseArray"  # any type: the rules look at the topic part of the key


def guide_blocks() -> list[tuple[str, str]]:
    """The section's fenced code blocks as (language, text), in order."""
    text = GUIDE.read_text()
    assert SECTION in text, f"{GUIDE} has no section {SECTION!r}"
    section = text.split(SECTION, 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^```(\w+)\n(.*?)^```$", section, flags=re.MULTILINE | re.DOTALL)


def guide_block(language: str, contains: str) -> str:
    """The one block in `language` that contains `contains`."""
    found = [body for lang, body in guide_blocks() if lang == language and contains in body]
    assert len(found) == 1, f"{len(found)} {language} blocks with {contains!r} in the guide's section"
    return found[0]


@dataclass(frozen=True)
class Guide:
    router: str  # the router's JSON5
    logins: dict[str, str]  # user -> password, from the dictionary block
    bridge: str  # the bridge's JSON5 config file
    operator_override: str  # the ZENOH_CONFIG_OVERRIDE a commanding node exports

    @property
    def commanders(self) -> list[str]:
        """The usernames the router's ACL names in its subjects."""
        config = zenoh.Config.from_json5(self.router)
        subjects = json.loads(config.get_json("access_control/subjects"))  # Zenoh hands back JSON text
        return [name for subject in subjects for name in subject["usernames"] or []]


def read_guide() -> Guide:
    dictionary = guide_block("text", ":change-this-")
    logins = dict(line.split(":", 1) for line in dictionary.split())  # one user:password a line
    override = re.search(r"ZENOH_CONFIG_OVERRIDE='([^']*)'", guide_block("bash", "ZENOH_CONFIG_OVERRIDE"))
    assert override is not None
    return Guide(
        router=guide_block("json5", "access_control"),
        logins=logins,
        bridge=guide_block("json5", 'mode: "client"'),
        operator_override=override.group(1),
    )


@dataclass
class Heard:
    """Payloads a subscriber got, by key, with a condition to wait on."""

    payloads: list[tuple[str, bytes]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def __call__(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.payloads.append((str(sample.key_expr), sample.payload.to_bytes()))

    def has(self, payload: bytes) -> bool:
        with self.lock:
            return any(got == payload for _, got in self.payloads)


@dataclass
class Site:
    """The guide's router, and how to open a client of it."""

    guide: Guide
    endpoint: str
    router: zenoh.Session
    sessions: list[zenoh.Session] = field(default_factory=list)

    def client(self, pairs: list[tuple[str, str]]) -> zenoh.Session:
        config = zenoh.Config()
        for key, value in [("mode", '"client"'), ("scouting/multicast/enabled", "false"), *pairs]:
            config.insert_json5(key, value)
        config.insert_json5("connect/endpoints", json.dumps([self.endpoint]))
        opened = zenoh.open(config)
        self.sessions.append(opened)
        return opened

    def login(self, user: str) -> zenoh.Session:
        auth = [("transport/auth/usrpwd/user", json.dumps(user)),
                ("transport/auth/usrpwd/password", json.dumps(self.guide.logins[user]))]  # fmt: skip
        return self.client(auth)

    def operator(self) -> zenoh.Session:
        """A commanding node, logged in by the guide's ZENOH_CONFIG_OVERRIDE as rmw_zenoh reads it."""
        return self.client(bridge_session.overrides_from_env(self.guide.operator_override))

    def bridge(self, tmp_path: Path) -> zenoh.Session:
        """The bridge's session, made as the transport makes it from `zenoh.config_file` and the
        `connect` setting (which wins over the file's)."""
        file = tmp_path / "zenoh-bridge.json5"
        file.write_text(self.guide.bridge)
        path, pairs = bridge_session.session_config(str(file), {"connect": [self.endpoint]}, {}, {})
        opened = zenoh.open(bridge_session.make_config(path, pairs))
        self.sessions.append(opened)
        return opened


@pytest.fixture
def site(tmp_path: Path) -> Iterator[Site]:
    guide = read_guide()
    users = tmp_path / "users.txt"
    users.write_text("".join(f"{user}:{password}\n" for user, password in guide.logins.items()))
    config = zenoh.Config.from_json5(guide.router)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    config.insert_json5("listen/endpoints", json.dumps([endpoint]))
    config.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(str(users)))
    config.insert_json5("scouting/multicast/enabled", "false")
    running = Site(guide, endpoint, zenoh.open(config))
    yield running
    for opened in reversed(running.sessions):
        opened.close()  # type: ignore[no-untyped-call]
    running.router.close()  # type: ignore[no-untyped-call]


DOMAIN = int(os.environ.get("ROS_DOMAIN_ID", "0"))
COMMAND = data_key(DOMAIN, "/lcm_in/IIWA_COMMAND", TYPE)
OPEN = data_key(DOMAIN, "/drake/poses", TYPE)


def put_until(session: zenoh.Session, key: str, payload: bytes, arrived: Callable[[], bool]) -> bool:
    """Put `payload` on `key` every half second until `arrived()`: the subscriber's declaration
    reaches the router in its own time, and a put before it is routed nowhere."""
    for _ in range(40):
        session.put(key, payload)
        if wait_for(arrived, timeout=0.5):
            return True
    return False


def test_the_guides_names_fit_together() -> None:
    guide = read_guide()
    assert guide.commanders == ["operator"]
    assert set(guide.logins) == {"operator", "bridge", "viewer"}
    assert 'user="operator"' in guide.operator_override
    assert COMMAND.startswith(f"{DOMAIN}/lcm_in/IIWA_COMMAND/geometry_msgs::msg::dds_::PoseArray_/RIHS01_")


def test_only_the_named_login_commands_and_other_keys_stay_open(site: Site, tmp_path: Path) -> None:
    bridge = site.bridge(tmp_path)
    heard = Heard()
    bridge.declare_subscriber(OPEN, heard)  # first: declared in order, so it is in place when the next is
    bridge.declare_subscriber(COMMAND, heard)

    operator = site.operator()
    assert put_until(operator, COMMAND, b"from operator", lambda: heard.has(b"from operator"))

    # The viewer's command, then a message on an open key from the same session: once the second
    # has arrived, the first would have too, had the router let it through.
    viewer = site.login("viewer")
    viewer.put(COMMAND, b"from viewer")
    assert put_until(viewer, OPEN, b"viewer on an open key", lambda: heard.has(b"viewer on an open key"))
    assert not heard.has(b"from viewer"), heard.payloads


def test_a_session_without_a_login_or_with_a_wrong_password_is_refused(site: Site) -> None:
    with pytest.raises(zenoh.ZError):
        site.client([])
    wrong = [("transport/auth/usrpwd/user", '"viewer"'), ("transport/auth/usrpwd/password", '"guess"')]
    with pytest.raises(zenoh.ZError):
        site.client(wrong)


def test_a_wildcard_publication_passes_the_rule_as_the_guide_warns(site: Site, tmp_path: Path) -> None:
    """The guide's first limit: `**` is not contained in `*/lcm_in/**`, and reaches the command
    subscription. Should Zenoh start judging such publications, this fails and the guide must change."""
    bridge = site.bridge(tmp_path)
    heard = Heard()
    bridge.declare_subscriber(COMMAND, heard)
    operator = site.operator()
    assert put_until(operator, COMMAND, b"from operator", lambda: heard.has(b"from operator"))

    viewer = site.login("viewer")
    assert put_until(viewer, "**", b"viewer on **", lambda: heard.has(b"viewer on **"))
    assert ("**", b"viewer on **") in heard.payloads


def test_the_bridge_drops_a_sample_put_on_a_wildcard_key() -> None:
    """What the rule above lets through commands nothing: the bridge takes a command only on the
    concrete key it subscribed to, and counts the rest."""
    from collections import Counter
    from types import SimpleNamespace

    from viewer_bridge.transports.base import CDR, MessageType, Received
    from viewer_bridge.transports.zenoh import entities

    errors: Counter[str] = Counter()
    delivered: list[Received] = []
    on_sample = entities.ros_receiver(
        "/lcm_in/IIWA_COMMAND",
        MessageType("drake_lcm_msgs/msg/LcmtIiwaCommand", CDR),
        [delivered.append],
        errors,
    )
    payload = SimpleNamespace(to_bytes=lambda: b"\0\1\0\0" + bytes(16))
    for key in ("**", "0/**", "0/*/IIWA_COMMAND/T/H", "0/lcm_in/$*"):
        on_sample(SimpleNamespace(key_expr=key, attachment=None, payload=payload))
    assert errors == {"wildcard_key": 4} and not delivered
