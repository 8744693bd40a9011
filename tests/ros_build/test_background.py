"""Interface packages built while the bridge runs (viewer_bridge/ros_build/background.py), through the router.

A route to ROS 2 whose type is not built waits (its messages counted as `waiting_for_build`) while
another route keeps flowing; once the package is built in the background the route publishes, and
an rclpy subscriber in this process receives its messages. A build that fails is one error line
naming the package and its log, and a count.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, ClassVar

import lcm
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from tests.conftest import lcm_url
from tests.peers import RosProbe, wait_for
from tests.ros_interfaces_corpus import ROUTER, ROUTER_DEFINITIONS
from viewer_bridge.config.bridge import load_config
from viewer_bridge.errors import RosInterfaceError
from viewer_bridge.ros_build import interfaces as ros_interfaces
from viewer_bridge.ros_build.background import BuildState, InterfaceBuilder
from viewer_bridge.router.router import Router
from viewer_bridge.translators.base import Output, Outputs, Translator
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.transports.base import CDR, LCM, MessageType, Received
from viewer_bridge.transports.ros2 import message_class

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)

COUNTER = f"{ROUTER}/msg/Counter"
BAD = "vbtest_bad_router_lcm_msgs"
BAD_DEFINITIONS = {f"{BAD}/msg/Bad": "float64 jointAngles\n"}  # rosidl: field names are lower case
STORE = get_typestore(Stores.ROS2_JAZZY)
STORE.register(get_types_from_msg(ROUTER_DEFINITIONS[COUNTER], COUNTER))
STORE.register(get_types_from_msg(BAD_DEFINITIONS[f"{BAD}/msg/Bad"], f"{BAD}/msg/Bad"))


def definitions(package: str) -> dict[str, str]:
    """The router's `ros_definitions` hook for these tests: the packages it may build."""
    known = {**ROUTER_DEFINITIONS, **BAD_DEFINITIONS}
    return {name: text for name, text in known.items() if name.startswith(f"{package}/")}


class CounterCdr(Translator):
    """Any LCM message whose bytes are a decimal count -> a Counter of it (a type built late)."""

    reads = (MessageType("*", LCM),)
    outputs: ClassVar[tuple[Output, ...]] = (Output("", MessageType(COUNTER, CDR)),)

    def translate(self, message: Received) -> Outputs:
        count = int(message.data)
        counter = STORE.types[COUNTER](count=count, label=f"n{count}", values=_values(count))
        return [(0, bytes(STORE.serialize_cdr(counter, COUNTER)))]


class BadCdr(Translator):
    """Any LCM message -> a message of a type whose package cannot be built."""

    reads = (MessageType("*", LCM),)
    outputs: ClassVar[tuple[Output, ...]] = (Output("", MessageType(f"{BAD}/msg/Bad", CDR)),)

    def translate(self, message: Received) -> Outputs:
        bad = STORE.types[f"{BAD}/msg/Bad"](jointAngles=float(message.data))
        return [(0, bytes(STORE.serialize_cdr(bad, f"{BAD}/msg/Bad")))]


class StringCdr(Translator):
    """Any LCM message -> std_msgs/String of its text (an installed type: flows from the start)."""

    reads = (MessageType("*", LCM),)
    outputs: ClassVar[tuple[Output, ...]] = (Output("", MessageType("std_msgs/msg/String", CDR)),)

    def translate(self, message: Received) -> Outputs:
        text = STORE.types["std_msgs/msg/String"](data=message.data.decode())
        return [(0, bytes(STORE.serialize_cdr(text, "std_msgs/msg/String")))]


class CounterText(Translator):
    """A Counter from ROS 2 (a type built late) -> its count as LCM text."""

    reads = (MessageType(COUNTER, CDR),)
    outputs: ClassVar[tuple[Output, ...]] = (Output("", MessageType("*", LCM)),)

    def translate(self, message: Received) -> Outputs:
        return [(0, str(STORE.deserialize_cdr(message.data, COUNTER).count).encode())]


def _values(count: int) -> Any:
    import numpy as np

    return np.array([count, -count, 0.5], dtype=np.float64)


CONFIG = """\
lcm: {{url: "{url}"}}
ros: {{node: vb_build_test}}
routes:
  - name: late
    source: {{transport: lcm, name: VB_LATE}}
    translator: vbtest_counter_cdr
    destination: {{transport: ros, name: /vb_test/late}}
    rate: {{policy: all}}
  - name: broken
    source: {{transport: lcm, name: VB_BROKEN}}
    translator: vbtest_bad_cdr
    destination: {{transport: ros, name: /vb_test/broken}}
    rate: {{policy: all}}
  - name: back
    source: {{transport: ros, name: /vb_test/late_in}}
    translator: vbtest_counter_text
    destination: {{transport: lcm, name: VB_BACK}}
    rate: {{policy: all}}
  - name: text
    source: {{transport: lcm, name: VB_TEXT}}
    translator: vbtest_string_cdr
    destination: {{transport: ros, name: /vb_test/text}}
    rate: {{policy: all}}
"""


BUILD_FAILED = "publish:TransportUnavailable"  # a failed build refuses each message, counted as an error


@pytest.fixture
def translators(monkeypatch: pytest.MonkeyPatch) -> None:
    """The test translators, as a plugin's would be found by name."""
    ours: dict[str, type[Translator]] = {
        "vbtest_counter_cdr": CounterCdr,
        "vbtest_bad_cdr": BadCdr,
        "vbtest_string_cdr": StringCdr,
        "vbtest_counter_text": CounterText,
    }
    found = TRANSLATORS.get  # every look-up (the config's, the router's) goes through `get`
    monkeypatch.setattr(TRANSLATORS, "get", lambda name: ours.get(name) or found(name))


@pytest.fixture
def not_built() -> Iterator[None]:
    """The router package removed from the venv: the bridge must build it (and leaves it built)."""
    ros_interfaces.uninstall([ROUTER])
    assert ROUTER not in sys.modules, "an earlier test imported it: run this test in a process of its own"
    yield


@pytest.mark.timeout(2400)  # waits up to 900 s for each of two builds
def test_a_route_waits_for_its_build_while_the_others_flow_then_publishes(
    translators: None, not_built: None, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="viewer_bridge")
    path = tmp_path / "late.yaml"
    url = lcm_url(7)
    path.write_text(CONFIG.format(url=url))
    router = Router(load_config(path), ros_definitions=definitions)
    probe = RosProbe("vb_build_peer")
    bus = lcm.LCM(url)
    stop = threading.Event()

    def send() -> None:  # each route's channel at 20 Hz, as a live bus would
        count = 0
        while not stop.is_set():
            count += 1
            for channel in ("VB_LATE", "VB_BROKEN", "VB_TEXT"):
                bus.publish(channel, str(count).encode())
            time.sleep(0.05)

    sender = threading.Thread(target=send, daemon=True)
    try:
        texts = probe.subscribe("/vb_test/text", "std_msgs/msg/String")
        router.start()
        sender.start()
        # The installed type flows while the other two packages are built (or fail to).
        assert probe.wait_for(lambda: len(texts) >= 5, timeout=60), "the installed type's route did not flow"
        waiting = router.snapshot()["routes"]["late"]["held"].get("VB_LATE", {}).get("waiting_for_build", 0)
        assert waiting > 0 and router.snapshot()["routes"]["late"]["messages_out"] == 0
        assert router.transports["ros"].builder is not None  # type: ignore[attr-defined]
        builder: InterfaceBuilder = router.transports["ros"].builder  # type: ignore[attr-defined]
        assert builder.wait(ROUTER, timeout=900).state is BuildState.READY
        assert builder.wait(BAD, timeout=900).state is BuildState.FAILED
        # Built after this process started, and importable in it: the subscriber needs its class.
        counters = probe.subscribe("/vb_test/late", COUNTER)
        assert probe.wait_for(lambda: len(counters) >= 3, timeout=60), "the built type was never published"
        assert wait_for(lambda: router.snapshot()["routes"]["broken"]["errors"].get(BUILD_FAILED, 0) > 0)
        # The other way: the route from ROS 2 subscribed once the type was built.
        back: list[bytes] = []
        bus.subscribe("VB_BACK", lambda _, data: back.append(data))
        publisher = probe.publisher("/vb_test/late_in", COUNTER)
        assert probe.wait_for(lambda: publisher.get_subscription_count() == 1, timeout=60)
        publisher.publish(message_class(COUNTER)(count=-42, label="x"))
        assert wait_for(lambda: bus.handle_timeout(50) is not None and b"-42" in back, timeout=60)
    finally:
        stop.set()
        router.close()
        probe.close()
    first = counters[0]
    assert first.label == f"n{first.count}" and list(first.values) == [first.count, -first.count, 0.5]
    stats = router.snapshot()["routes"]
    late, broken, text = stats["late"], stats["broken"], stats["text"]
    assert late["messages_out"] >= 3 and late["errors"] == {}
    assert late["held"]["VB_LATE"]["waiting_for_build"] >= waiting  # dropped while waiting, counted
    assert text["errors"] == {} and text["warnings"] == {} and text["messages_out"] >= 5
    assert set(broken["errors"]) == {BUILD_FAILED} and broken["messages_out"] == 0
    log = ros_interfaces.log_path(sys.prefix, BAD)
    failures = [record.getMessage() for record in caplog.records if record.levelno >= logging.ERROR]
    assert failures == [
        f"ROS 2 interface package {BAD} not built: configuring {BAD} failed (exit 1); its log: {log}"
    ]
    said = [record.getMessage() for record in caplog.records]
    assert f"building {ROUTER} (1 type) into {sys.prefix}" in said
    assert any(line.startswith(f"built {ROUTER} in ") for line in said)


def test_a_builder_asked_for_a_package_it_does_not_know_says_so() -> None:
    builder = InterfaceBuilder(definitions)
    assert builder.knows(ROUTER) and builder.knows(BAD) and not builder.knows("std_msgs")
    assert builder.status("std_msgs").state is BuildState.ABSENT


@pytest.mark.timeout(1200)  # waits up to 600 s for the build, then builds it again
def test_a_failed_build_is_failed_with_the_reason(caplog: pytest.LogCaptureFixture) -> None:
    builder = InterfaceBuilder(definitions)
    assert builder.request(BAD).state is BuildState.BUILDING
    status = builder.wait(BAD, timeout=600)
    assert status.state is BuildState.FAILED
    with pytest.raises(RosInterfaceError) as raised:
        ros_interfaces.build(BAD_DEFINITIONS)
    assert status.reason == f"ROS 2 interface package {BAD} not built: {raised.value}"
    assert builder.request(BAD) == status  # asked again: not built again


@pytest.mark.timeout(1800)  # three builds of the package
def test_changed_definitions_rebuild_the_package_and_leave_nothing_of_the_old_one(
    capsys: pytest.CaptureFixture[str],
) -> None:
    ros_interfaces.build(ROUTER_DEFINITIONS)  # as the router test leaves it (built when it ran first)
    share = Path(sys.prefix) / "share" / ROUTER
    assert (share / "msg" / "Counter.msg").exists()
    changed = {f"{ROUTER}/msg/Tally": "int64 count\n"}
    try:
        assert ros_interfaces.build(changed, log=print) == [ROUTER]
        assert f"building {ROUTER} (1 type) into {sys.prefix}" in capsys.readouterr().out
        assert (share / "msg" / "Tally.msg").exists() and not (share / "msg" / "Counter.msg").exists()
        assert ros_interfaces.build(changed) == []
    finally:
        ros_interfaces.build(ROUTER_DEFINITIONS)
    assert (share / "msg" / "Counter.msg").exists() and not (share / "msg" / "Tally.msg").exists()


def test_a_running_bridge_never_installs_what_a_build_needs(tmp_path: Path) -> None:
    """A message on a bus must not make the bridge install software: in an environment without the
    build's wheels the builder refuses, naming what to install, and installs nothing."""
    import importlib.metadata
    import venv

    prefix = tmp_path / "bare"
    venv.EnvBuilder(with_pip=False, symlinks=True).create(prefix)
    site = next(prefix.glob("lib/python*/site-packages"))
    before = sorted(path.name for path in site.iterdir())
    builder = InterfaceBuilder(definitions, prefix=prefix)
    assert builder.request(ROUTER).state is BuildState.BUILDING
    status = builder.wait(ROUTER, timeout=120)
    assert status.state is BuildState.FAILED, status
    assert (
        "pip install 'viewer-bridge[ros-build]'" in status.reason and "ros-jazzy-ament-cmake" in status.reason
    )
    assert sorted(path.name for path in site.iterdir()) == before  # nothing was installed
    assert not list(importlib.metadata.distributions(path=[str(site)]))
