"""Shared fixtures: lcm-gen's generated Python for our schemas, and real Drake traffic; every test's
deadline, and the end of every child process it started."""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import sysconfig
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import lcm
import pytest

import viewer_bridge.examples
from tests.claims import lcm_port, ros_domain
from tests.process_groups import ChildGroups
from viewer_bridge.errors import MissingExtra
from viewer_bridge.formats.drake.draw import poses_from_draw
from viewer_bridge.formats.drake.load import decode_load
from viewer_bridge.lcmcodec.codecs import DRAW, LOAD_ROBOT, SCHEMA_DIR
from viewer_bridge.lcmcodec.serde import LcmMessage
from viewer_bridge.model.scene import LinkPoses, Scene
from viewer_bridge.transports.lcm import LcmEvent, read_log

SCRIPTS = Path(sysconfig.get_paths()["purelib"]) / "bin"  # the lcm wheel's real binaries

# ROS 2 traffic stays on this host, in a domain of this test process's own (before rclpy loads):
# no other test process on this machine has it while this one runs (tests/claims.py).
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ["ROS_DOMAIN_ID"] = str(ros_domain())


# Where every peer is installed (`./dev test`), a skipped test is a failure: a test that skips
# itself hides what it should check. Only a core-only run (tests/core_only/sitecustomize.py) may
# skip the tests whose peers it lacks (tests/optional.py).
CORE_ONLY = os.environ.get("VIEWER_BRIDGE_CORE_ONLY") == "1"
# Tests of an extra's own code, which a core-only run leaves out: the Foxglove format imports
# foxglove-schemas-protobuf, and the recorded load outputs include it.
collect_ignore_glob = ["formats/foxglove/*", "formats/test_load_fast_paths.py"] if CORE_ONLY else []


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()  # type: ignore[attr-defined]
    if (
        CORE_ONLY
        and call.excinfo is not None
        and call.excinfo.errisinstance((ModuleNotFoundError, MissingExtra))
    ):
        # A peer imported where a test (or what it calls) needs it, absent here: that test is skipped
        # (a converter says so as MissingExtra, naming the module).
        path, line, _ = item.location
        error = call.excinfo.value
        report.outcome = "skipped"
        needed = error.module if isinstance(error, MissingExtra) else error.name
        report.longrepr = (path, (line or 0) + 1, f"Skipped: needs {needed}")
    _skip_fails(report)


def pytest_collectreport(report: pytest.CollectReport) -> None:
    _skip_fails(report)


def _skip_fails(report: pytest.TestReport | pytest.CollectReport) -> None:
    if report.skipped and not CORE_ONLY:
        reason = report.longrepr[-1] if isinstance(report.longrepr, tuple) else report.longrepr
        report.outcome = "failed"
        report.longrepr = f"skipped ({reason}): a skip fails the run unless VIEWER_BRIDGE_CORE_ONLY=1"


# --- deadlines and child processes ---------------------------------------------------------------

CHILDREN = ChildGroups()


def pytest_configure(config: pytest.Config) -> None:
    CHILDREN.install()  # every child from here on runs in a process group of its own


def pytest_unconfigure(config: pytest.Config) -> None:
    CHILDREN.end_all()  # what session and module fixtures started and left
    CHILDREN.uninstall()


# The files that take minutes (measured with --durations on the 2-core machine), longest first.
# `./dev test` runs the suite on two pytest-xdist workers, a file at a time each, handed out in
# collection order: started first, each of these runs beside the many short files instead of
# after them, on a worker otherwise idle at the end.
LONGEST_FIRST = (
    "tests/test_bench_smoke.py",
    "tests/fuzz/test_fuzz_targets.py",
    "tests/test_wheel.py",
    "tests/ros_build/test_background.py",
    "tests/test_router.py",
    "tests/transports/zenoh/test_transport.py",
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rank = {path: index for index, path in enumerate(LONGEST_FIRST)}
    # stable: the rest as collected
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


@pytest.fixture(autouse=True)
def _children_ended_at_teardown() -> Iterator[None]:
    """The process groups this test started end with it (autouse, so set up first and torn down last)."""
    with CHILDREN.test_scope():
        yield


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_timeout_set_timer(item: pytest.Item, settings: Any) -> bool | None:
    """pytest-timeout's `thread` method, with the test named in the report and its children ended.

    A thread, not SIGALRM: a test stuck in C (rclpy, Zenoh, a socket) never returns to the
    interpreter to see a signal. The thread cannot fail the test and go on, so the run ends
    (exit 1); the child groups are ended first, since no teardown runs after os._exit.
    """
    if settings.method != "thread":
        return None  # pytest-timeout's own signal method; the teardown above still ends the children
    timer = threading.Timer(settings.timeout, _deadline_passed, (item, settings))
    timer.name = f"deadline of {item.nodeid}"
    timer.daemon = True

    def cancel() -> None:
        timer.cancel()
        timer.join()

    item.cancel_timeout = cancel  # type: ignore[attr-defined]  # what pytest-timeout's cancel hook calls
    timer.start()
    return True


def _deadline_passed(item: pytest.Item, settings: Any) -> None:
    import pytest_timeout

    if not settings.disable_debugger_detection and pytest_timeout.is_debugging():
        return
    terminal = item.config.get_terminal_writer()
    try:
        capture = item.config.pluginmanager.getplugin("capturemanager")
        captured = ("", "")
        if capture is not None:
            capture.suspend_global_capture(item)
            captured = capture.read_global_capture()
        terminal.sep("+", f"Timeout: {item.nodeid} ran past its {settings.timeout:g} s")
        for title, text in zip(("Captured stdout", "Captured stderr"), captured, strict=True):
            if text:
                terminal.sep("~", title)
                terminal.write(text)
        pytest_timeout.dump_stacks(terminal)  # every thread's stack but this timer's
        terminal.sep("+", f"Timeout: {item.nodeid}: ending its child processes and the run")
    finally:
        terminal.flush()
        try:
            CHILDREN.end_all(grace=5)
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(1)


def lcm_url(offset: int = 0) -> str:
    """A multicast URL of this test process's own (ttl=0 keeps it on this host): its port, one of
    a block no other test process on this machine has while this one runs (tests/claims.py)."""
    return f"udpm://239.255.76.67:{lcm_port(offset)}?ttl=0"


@pytest.fixture(scope="session")
def lcmgen(tmp_path_factory: pytest.TempPathFactory) -> dict[str, type]:
    """lcm-gen's own generated Python classes for every schema in lcmtypes/, by full name."""
    out = tmp_path_factory.mktemp("lcmgen")
    schemas = sorted(str(path) for path in SCHEMA_DIR.glob("*.lcm"))
    subprocess.run([str(SCRIPTS / "lcm-gen"), "--python", "--ppath", str(out), *schemas], check=True)
    sys.path.insert(0, str(out))
    classes: dict[str, type] = {}
    before = set(sys.modules)
    try:
        for package in ("drake", "robotlocomotion"):
            for path in (out / package).glob("*.py"):
                if path.stem == "__init__":
                    continue
                # Load by file so that Drake's installed `drake` package does not shadow ours.
                spec = importlib.util.spec_from_file_location(f"lcmgen_{package}.{path.stem}", path)
                assert spec and spec.loader
                module: ModuleType = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
                classes[f"{package}.{path.stem}"] = getattr(module, path.stem)
    finally:
        sys.path.remove(str(out))
        # The generated modules' own `import drake.…` imported this folder's `drake` package: it
        # must not stand for pydrake's in later tests (TypeLibrary reads Drake's types from it).
        for name in set(sys.modules) - before:
            if str(getattr(sys.modules[name], "__file__", "")).startswith(str(out)):
                del sys.modules[name]
    return classes


EXAMPLES = Path(viewer_bridge.examples.__file__).parent  # the example simulations, run as scripts
DRAKE_SCENE_SCRIPT = EXAMPLES / "shapes.py"


def record_log(log: Path, url: str, simulation: list[str]) -> Path:
    """`log`, recorded by the real lcm-logger on `url` while the `simulation` command runs."""
    logger = subprocess.Popen(
        [str(SCRIPTS / "lcm-logger"), "--lcm-url", url, "-f", str(log)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        _until_logged(url, log, b"logger listening")  # before the simulation's first message
        subprocess.run(simulation, check=True, timeout=300)
        _until_logged(url, log, b"simulation done")  # after its last message
    finally:
        logger.send_signal(signal.SIGINT)
        logger.wait(timeout=60)
    return log


def _until_logged(url: str, log: Path, mark: bytes) -> None:
    def logged() -> bool:
        return log.exists() and any(event.data == mark for event in read_log(log, SYNC_CHANNEL))

    publish_until(url, mark, logged)


SYNC_CHANNEL = "TEST_SYNC"


def read_line(stream: Any, what: str, timeout: float = 60.0) -> str:
    """The next line a child writes on `stream` (a pipe), within `timeout` seconds, else an
    AssertionError naming `what` was waited for: a child that hangs before writing it must fail
    the test, not stall the run (`readline` alone never returns). Read on a thread of its own."""
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.append(stream.readline()), daemon=True)
    reader.start()
    reader.join(timeout)
    assert lines, f"no {what} within {timeout:g} s"
    return str(lines[0])


def publish_until(
    url: str, mark: bytes, received: Callable[[], bool], timeout: float = 120, channel: str = SYNC_CHANNEL
) -> None:
    """Publish `mark` on `channel` until `received()` (UDP may drop one).

    A listener's socket queues datagrams in the order they arrive, so once it has read a mark
    sent after a peer's last message, it has read that message too: no fixed wait needed.
    """
    bus = lcm.LCM(url)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        bus.publish(channel, mark)
        time.sleep(0.1)
        if received():
            return
    raise AssertionError(f"{mark!r} on {url} never arrived")


@pytest.fixture(scope="session")
def drake_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An LCM log recorded by the real lcm-logger while a pydrake simulation runs DrakeVisualizer."""
    pytest.importorskip("pydrake")  # the simulation's (a core-only run skips the tests of Drake's traffic)
    folder = tmp_path_factory.mktemp("drake")
    url = lcm_url()
    return record_log(
        folder / "drake.lcmlog", url, [sys.executable, str(DRAKE_SCENE_SCRIPT), url, str(folder)]
    )


@pytest.fixture(scope="session")
def drake_events(drake_log: Path) -> list[LcmEvent]:
    """Drake's viewer traffic from the log (DrakeLcm's own LCM_SELF_TEST left out)."""
    return list(read_log(drake_log, "DRAKE_.*"))


@pytest.fixture(scope="session")
def drake_mesh_dir(drake_log: Path) -> Iterator[Path]:
    yield drake_log.parent


@dataclass(frozen=True)
class Capture:
    """One role of the real Drake capture: its raw load message, that load as a scene, the last draw."""

    load: LcmMessage
    scene: Scene
    poses: LinkPoses

    def raw_geometries(self) -> list[tuple[str, LcmMessage]]:
        """(link name, lcmt_viewer_geometry_data) in scene order: the oracle tests compare against."""
        return [(link.name, geometry) for link in self.load.link for geometry in link.geom]


@pytest.fixture(scope="session")
def drake_capture(drake_events: list[LcmEvent]) -> dict[str, Capture]:
    """role ("ILLUSTRATION", "PROXIMITY") -> what Drake published for it."""
    captures = {}
    for role in ("ILLUSTRATION", "PROXIMITY"):
        load = next(e.data for e in drake_events if e.channel == f"DRAKE_VIEWER_LOAD_ROBOT_{role}")
        draw = [e.data for e in drake_events if e.channel == f"DRAKE_VIEWER_DRAW_{role}"][-1]
        scene = decode_load(load)
        poses = poses_from_draw(DRAW.decode(draw))
        captures[role] = Capture(LOAD_ROBOT.decode(load), scene.with_poses(poses), poses)
    return captures


@pytest.fixture(scope="session")
def debian_ign_msgs(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    """The `ignition.msgs` package generated by protoc from Debian's libignition-msgs-dev files."""
    out = tmp_path_factory.mktemp("ignition_protos")
    protos = sorted(str(path) for path in IGN_MSGS_DIR.glob("ignition/msgs/*.proto"))
    assert protos, f"{IGN_MSGS_DIR} has no .proto files: install Debian's libignition-msgs-dev"
    command = [sys.executable, "-m", "grpc_tools.protoc", f"-I{IGN_MSGS_DIR}", f"--python_out={out}", *protos]
    subprocess.run(command, check=True)
    sys.path.insert(0, str(out))
    try:
        modules = {
            path.stem: importlib.import_module(f"ignition.msgs.{path.stem}")
            for path in sorted((out / "ignition" / "msgs").glob("*_pb2.py"))
        }
    finally:
        sys.path.remove(str(out))
    package = ModuleType("debian_ignition_msgs")
    for module in modules.values():
        for name in dir(module):
            if not name.startswith("_"):
                setattr(package, name, getattr(module, name))
    return package


IGN_MSGS_DIR = Path("/usr/include/ignition/msgs8")
