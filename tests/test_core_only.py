"""Tests where their peers are missing: the codec tests run in a core-only Python, and anywhere
else a skipped test fails the run (tests/conftest.py).

The core-only Python is this venv with tests/core_only/sitecustomize.py first on PYTHONPATH: rclpy,
the ROS 2 interfaces, pydrake and Drake's LCM types, foxglove, zenoh and moderngl cannot be
imported. The same by hand:

    VIEWER_BRIDGE_CORE_ONLY=1 PYTHONPATH=tests/core_only:. python -m pytest tests/formats tests/lcmcodec
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# Codec tests whose modules also hold tests that need rclpy or pydrake (their peers' oracles).
CODEC_TESTS = [
    "tests/formats/drake/test_draw.py",
    "tests/formats/ros/test_poses.py",
    "tests/formats/ros/test_image.py",
    "tests/formats/ign/test_poses.py",
    "tests/lcmcodec/test_schema.py",
    "tests/model/test_pose_math.py",
]

if os.environ.get("VIEWER_BRIDGE_SKIP_PROBE") == "1":  # only in the probe's own run, below

    def test_probe_that_skips() -> None:
        pytest.skip("the probe of the rule that a skip fails the run")


def pytest_run(*args: str, core_only: bool, **env: str) -> subprocess.CompletedProcess[str]:
    environment = {**os.environ, **env, "PYTHONPATH": str(ROOT)}
    environment.pop("VIEWER_BRIDGE_CORE_ONLY", None)
    if core_only:
        environment.update(
            VIEWER_BRIDGE_CORE_ONLY="1", PYTHONPATH=f"{ROOT / 'tests' / 'core_only'}{os.pathsep}{ROOT}"
        )
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rs", *args],
        cwd=ROOT,
        env=environment,
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )


@pytest.mark.timeout(2000)  # two pytest runs of up to 900 s each
def test_a_skip_fails_the_run_unless_the_run_is_core_only() -> None:
    probe = (f"{Path(__file__).relative_to(ROOT)}::test_probe_that_skips",)
    full = pytest_run(*probe, core_only=False, VIEWER_BRIDGE_SKIP_PROBE="1")
    assert full.returncode == 1 and "1 failed" in full.stdout, full.stdout
    assert "a skip fails the run unless VIEWER_BRIDGE_CORE_ONLY=1" in full.stdout
    core = pytest_run(*probe, core_only=True, VIEWER_BRIDGE_SKIP_PROBE="1")
    assert core.returncode == 0 and "1 skipped" in core.stdout, core.stdout


def test_the_core_only_python_cannot_import_the_peers() -> None:
    code = (
        "import importlib, sys\n"
        "for name in sys.argv[1:]:\n"
        "    try:\n        importlib.import_module(name)\n"
        "    except ModuleNotFoundError:\n        print(name)"
    )
    peers = ["rclpy", "pydrake", "drake", "geometry_msgs.msg", "foxglove", "zenoh", "moderngl"]
    environment = {**os.environ, "PYTHONPATH": f"{ROOT / 'tests' / 'core_only'}{os.pathsep}{ROOT}"}
    result = subprocess.run(
        [sys.executable, "-c", code, *peers, "numpy", "viewer_bridge.formats.ros.poses"],
        env=environment, capture_output=True, text=True, timeout=120, check=True,
    )  # fmt: skip
    assert result.stdout.split() == peers


@pytest.mark.timeout(1200)  # a pytest run of up to 900 s
def test_codec_tests_run_where_rclpy_and_pydrake_are_missing() -> None:
    result = pytest_run(*CODEC_TESTS, "-m", "not slow", core_only=True)
    assert result.returncode == 0, result.stdout[-3000:]
    counts = {
        kind: int(number) for number, kind in re.findall(r"(\d+) (passed|skipped|failed)", result.stdout)
    }
    assert counts.get("failed", 0) == 0 and counts["passed"] >= 20, result.stdout[-3000:]
    # What needs a peer is skipped, saying which; the rest ran.
    assert counts["skipped"] >= 5 and re.search(
        r"(needs|could not import '?)(rclpy|pydrake|drake)", result.stdout
    )


def test_the_library_guides_type_store_section_runs_in_a_core_only_python(tmp_path: Path) -> None:
    """docs/library.md's type store, as the docs test runs it (its substitutions), in a Python where
    no extra can be imported: the store needs the core install alone."""
    from tests.test_docs import blocks, substituted

    page = (ROOT / "docs" / "library.md").read_text()
    (block,) = [block for block in blocks(page, ("python",)) if "viewer_bridge.lcm_types(" in block]
    script = tmp_path / "type_store.py"
    script.write_text(substituted(block) + "\nprint('type store ok')\n")
    environment = {
        **os.environ,
        "PYTHONPATH": f"{ROOT / 'tests' / 'core_only'}:{ROOT}",
        "VIEWER_BRIDGE_CORE_ONLY": "1",
    }
    result = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=environment, capture_output=True,
                            text=True, timeout=300)  # fmt: skip
    assert result.returncode == 0 and "type store ok" in result.stdout, result.stderr[-3000:]
    probe = subprocess.run(
        [sys.executable, "-c", "import rclpy"], env=environment, capture_output=True, timeout=60
    )
    assert probe.returncode != 0  # the extras really are out of reach there
