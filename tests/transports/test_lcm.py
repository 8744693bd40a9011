"""The LCM transport's receive buffer, and the drops the kernel counts when it overflows anyway."""

from __future__ import annotations

import errno
import logging
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.conftest import lcm_url
from viewer_bridge.transports import lcm as lcm_transport
from viewer_bridge.transports.lcm import LcmSettings, LcmTransport, with_receive_buffer
from viewer_bridge.util.hints import DEBUG_ENV

pytestmark = pytest.mark.e2e  # starts peers or bridges (`./dev test --stress N` repeats it)


def rmem_max() -> int:
    return int(Path("/proc/sys/net/core/rmem_max").read_text())


def test_a_udpm_url_asks_for_a_large_buffer_capped_by_the_kernel_limit() -> None:
    url = "udpm://239.255.76.67:7667?ttl=0"
    assert with_receive_buffer(url) == f"{url}&recv_buf_size={min(rmem_max(), lcm_transport.RECEIVE_BUFFER)}"
    granted = min(rmem_max(), lcm_transport.RECEIVE_BUFFER)
    assert (
        with_receive_buffer("udpm://239.255.76.67:7667")
        == f"udpm://239.255.76.67:7667?recv_buf_size={granted}"
    )
    assert with_receive_buffer(f"{url}&recv_buf_size=1000") == f"{url}&recv_buf_size=1000"  # the user's own
    assert with_receive_buffer("memq://") == "memq://"


def test_the_limit_is_explained_once_per_machine_with_the_sysctl_to_raise_it(
    caplog: pytest.LogCaptureFixture, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))  # a machine that never gave the hint
    monkeypatch.delenv(DEBUG_ENV, raising=False)
    runs = iter(range(3))

    def advice() -> list[str]:
        """A run of its own: a size this process never asked for (it remembers the sizes it did),
        asked for twice."""
        wanted = rmem_max() * 2 + next(runs)
        caplog.clear()
        with caplog.at_level("INFO", logger="viewer_bridge"):
            with_receive_buffer("udpm://239.255.76.67:7667?ttl=0", wanted)
            with_receive_buffer("udpm://239.255.76.67:7668?ttl=0", wanted)
        return [record.getMessage() for record in caplog.records if "rmem_max" in record.getMessage()]

    def said(wanted: int) -> list[str]:
        return [
            f"LCM receive buffer: {wanted // 1024} kB asked, the kernel allows {rmem_max() // 1024} kB "
            f"(net.core.rmem_max); for fewer drops under load: sudo sysctl -w net.core.rmem_max={wanted}"
        ]

    assert advice() == said(rmem_max() * 2)
    assert (tmp_path / "viewer-bridge" / "hints" / "rmem_max").is_file()
    assert advice() == []  # the next run on this machine: not again
    monkeypatch.setenv(DEBUG_ENV, "1")  # --debug: again
    assert advice() == said(rmem_max() * 2 + 2)


def test_what_the_kernel_drops_is_counted_as_the_transports_error() -> None:
    url = lcm_url(21)
    # A small buffer the user asked for and a reader that cannot keep up: the kernel must drop.
    # How many it drops depends on how fast LCM's receive thread drains the socket, so the test
    # checks the accounting instead: every datagram sent is either handled or counted as dropped.
    transport = LcmTransport(LcmSettings(url=f"{url}&recv_buf_size=100000"))
    unblocked = threading.Event()
    handled: list[int] = []

    def slow_reader(channel: str, data: bytes, received_us: int) -> None:
        unblocked.wait(60)
        handled.append(len(data))

    transport.bus.subscribe(".*", slow_reader)
    transport.start()
    sender = lcm_transport.Publisher(url)
    sent = 200
    try:
        assert transport.errors() == {}
        for _ in range(sent):
            sender.publish("FLOOD", bytes(60_000))
        # The reader is held on the first datagram, so the socket's buffer overflows.
        deadline = time.monotonic() + 60
        while not transport.errors().get("dropped_by_kernel") and time.monotonic() < deadline:
            time.sleep(0.02)
        dropped = transport.errors().get("dropped_by_kernel", 0)
        assert dropped > 0
        unblocked.set()
        deadline = time.monotonic() + 60
        while len(handled) + dropped < sent and time.monotonic() < deadline:
            time.sleep(0.02)
        assert len(handled) + dropped == sent
        assert transport.errors()["dropped_by_kernel"] == dropped
    finally:
        unblocked.set()
        transport.close()


KERNEL_DROPS_OUT_OF_FILES = """
import os, resource, sys
from viewer_bridge.transports.lcm import LcmBus
bus = LcmBus(sys.argv[1])
resource.setrlimit(resource.RLIMIT_NOFILE, (256, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
held = []
try:
    while True:
        held.append(os.open(os.devnull, os.O_RDONLY))
except OSError:
    pass
print(bus.kernel_drops())
"""


def test_the_kernel_drops_of_a_process_out_of_files_are_the_last_count_not_an_error() -> None:
    """Reading them lists /proc/self/fd, which takes a file: out of files (EMFILE), the stats
    report that asked once ended the whole bridge."""
    result = subprocess.run([sys.executable, "-c", KERNEL_DROPS_OUT_OF_FILES, lcm_url(22)],
                            capture_output=True, text=True, timeout=120)  # fmt: skip
    assert result.returncode == 0 and result.stdout == "0\n", result.stderr


def test_a_stats_report_that_cannot_be_made_is_skipped_and_said_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    from viewer_bridge.router import stats

    def out_of_files() -> dict[str, object]:
        raise OSError(errno.EMFILE, "Too many open files")

    stats._skipped.clear()  # said once per process: from here
    shown: list[dict[str, object]] = []
    view = type("View", (), {"show": lambda self, snapshot: shown.append(snapshot)})()
    with caplog.at_level(logging.WARNING):
        for _ in range(3):
            stats.report_safely(out_of_files, view, None)
        stats.report_safely(lambda: {"route": {}}, view, None)
    assert shown == [{"route": {}}]
    assert (
        len([record for record in caplog.records if "stats report was skipped" in record.getMessage()]) <= 1
    )


@pytest.mark.parametrize(
    ("patterns", "subscribed"),
    [
        (["DRAKE_VIEWER_DRAW(_A|_B)?", "CONTACT_RESULTS", "DIRECTOR_<([^<>]*)>"],
         "((CONTACT_RESULTS)|(DIRECTOR_<([^<>]*)>)|(DRAKE_VIEWER_DRAW(_A|_B)?))"),
        (["A", "(?!LCM_SELF_TEST$)(.*)"], ".*"),  # a lookahead: POSIX has none
        (["A(?:_X)?"], "((A(_X)?))"),  # a group that captures nothing is a group
        (["A_\\d+"], ".*"),  # an escape POSIX reads otherwise
        (["A.*?"], ".*"),  # lazy
        ([], ".*"),
    ],
)  # fmt: skip
def test_the_bus_subscribes_to_the_routes_channels_when_lcm_reads_them_as_python(
    patterns: list[str], subscribed: str
) -> None:
    assert lcm_transport.lcm_filter(patterns) == subscribed


def test_lcm_drops_the_channels_no_route_reads_before_python_sees_them() -> None:
    url = lcm_url(22)
    bus = lcm_transport.LcmBus(url)
    seen: list[str] = []
    bus.subscribe(
        lcm_transport.lcm_filter(["A(_X|_Y)?", "B_[0-9]+"]), lambda channel, *_: seen.append(channel)
    )
    bus.start()
    sender = lcm_transport.Publisher(url)
    try:
        for channel in ("A_X", "NOISE", "A_Z", "B_12", "AA", "B_", "A"):
            sender.publish(channel, b"x" * 2000)  # past a short message: LCM's fragment path
        sender.publish("A_Y", b"last")
        deadline = time.monotonic() + 60
        while "A_Y" not in seen and time.monotonic() < deadline:
            time.sleep(0.02)
        assert seen == ["A_X", "B_12", "A", "A_Y"]
    finally:
        bus.close()
