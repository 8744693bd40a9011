"""A short run of bench/fuzz.py: every target under atheris for a few thousand executions, no findings.

The long run (a million executions a target) is `.venv/bin/python bench/fuzz.py`.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.fuzz.targets import TARGETS
from viewer_bridge.config.bridge import load_config
from viewer_bridge.errors import ConfigError

BENCH = Path(__file__).resolve().parents[2] / "bench" / "fuzz.py"


def test_every_target_runs_under_atheris_without_findings() -> None:
    result = subprocess.run([sys.executable, str(BENCH), "--runs", "2000"], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    rows = {line.split()[0]: line for line in result.stdout.splitlines()[1:] if line.strip()}
    assert set(rows) == set(TARGETS)
    for row in rows.values():
        executions = int(row.split()[1])
        assert executions >= 2000 and row.endswith("none"), row


def test_a_config_that_is_not_utf8_is_a_config_error_naming_its_line(tmp_path: Path) -> None:
    """The fuzzer's first finding: a UnicodeDecodeError escaped the config loader."""
    path = tmp_path / "bridge.yaml"
    path.write_bytes(b"# fine\n# not \xff\xff text\nroutes: []\n")
    try:
        load_config(path)
    except ConfigError as error:
        assert str(error).startswith(f"{path}:2:") and "not UTF-8 text: byte 13 is 0xff" in str(error)
    else:
        raise AssertionError("no ConfigError")


def test_a_point_cloud2_with_a_huge_point_step_is_a_decode_error() -> None:
    """bench/fuzz.py's second finding (ros_point_cloud2, after 719,850 runs): an empty cloud whose
    point_step is past numpy's record limit raised ValueError ('integer won't fit into a C int')."""
    import base64

    import pytest

    from viewer_bridge.errors import DecodeError

    data = base64.b64decode(
        "AAEAAAAAAABAQg8ABgAAAHdvcmxkAAAAAQAAAAAAAAADAAAAAgAAAHgAAAAAAOkABwAAAAEAAAACAAAAeQAAAAQQAAAHAAAA"
        "AQAAAAIAAAB6AAAACAAAAAcAAAABAAAAAAAAAAwAAKkAAAAAAAAAAAAAAAAADAAAAHgAAAB4AAAA9v///83MzD3NzEw+mpmZ"
        "Ps3MzD4AAAA/mpkZPzMzMz/NzEw/ZmZmPwAAgD/NzIw/mpmZP2Zmpj8zM7M/AADAP83MzD8z8z8AAABAZmYGQM3MDEAzMxNA"
        "mpkZQAAAIEBmZiZAzcwsQDMzM0CamTlAAQ=="
    )
    with pytest.raises(DecodeError, match="point_step"):
        TARGETS["ros_point_cloud2"].run(data)


def test_a_destination_reaching_into_a_group_is_a_config_error(tmp_path: Path) -> None:
    """bench/fuzz.py's third finding: `{1.path}` (a dot for a colon) raised AttributeError."""
    import pytest

    path = tmp_path / "bridge.yaml"
    for template in ("/drake{1.path}/model_v", "/drake{1[a]}/x", "/drake{1[0]}/x"):
        path.write_text(
            "routes:\n  - name: r\n    source: {transport: lcm, name: 'DRAKE_VIEWER_DRAW(_PROXIMITY)?'}\n"
            f"    translator: drake_to_pose_array\n    destination: {{transport: ros, name: '{template}'}}\n"
        )
        with pytest.raises(ConfigError, match="is not a group number"):
            load_config(path)


def test_an_origin_against_many_stars_is_matched_at_once() -> None:
    """bench/fuzz.py's fourth finding (origin_match, after 4,339 runs): allowed origins were a
    regular expression, each `*` a `[^/]*`, and stars side by side backtracked for minutes on a
    65-byte input. The matcher is linear now; here a 64 kB origin (the longest head the front
    reads) against an entry of many stars, given a generous 30 s."""
    import threading

    from viewer_bridge.transports.origins import Origins, origin_matches

    found = TARGETS["origin_match"].run(
        b"***********@@@@@@@@@@@@@@@****\x01\x00\x00\x00\x00\x00\x00\x00****************(*********t"
    )
    assert found is False
    entry, origin = "https://*-*-*-*-*-*.example", "https://" + "-" * 64_000 + ".example.org"
    answers: list[bool] = []
    worker = threading.Thread(target=lambda: answers.append(Origins([entry]).allows(origin)), daemon=True)
    worker.start()
    worker.join(timeout=30)
    assert answers == [False]
    assert origin_matches(entry, "https://a-b-c-d-e-f.example") and not origin_matches(
        entry, "https://a-b/c-d-e-f.example"
    )


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_an_mcap_chunk_declaring_more_than_any_machine_holds_is_a_damaged_chunk(compression: str) -> None:
    """bench/fuzz.py's findings on mcap_reader (in its first thousands of runs): a chunk declaring
    2^64 - 1 bytes raised OverflowError (zstd's `max_length` is an ssize_t) and MemoryError (lz4
    allocates the `max_length` it is given before it reads). Each call now asks for at most 1 MiB."""
    import struct

    from lz4.frame import compress

    data = zstd_compress(b"x" * 10) if compression == "zstd" else compress(b"x" * 10)
    name = compression.encode()
    body = struct.pack("<QQQI", 0, 0, (1 << 64) - 1, 0) + struct.pack("<I", len(name)) + name
    body += struct.pack("<Q", len(data)) + data
    messages, damaged = TARGETS["mcap_reader"].run(struct.pack("<BQ", 0x06, len(body)) + body)
    assert (
        messages == []
        and damaged
        == ["bag.mcap: the chunk at byte 8: it holds 10 bytes where it declares 18446744073709551615"] * 2
    )  # read twice: for the topics, then for the messages


def zstd_compress(data: bytes) -> bytes:
    import sys

    if sys.version_info >= (3, 14):
        from compression import zstd
    else:
        from backports import zstd
    return bytes(zstd.compress(data))
