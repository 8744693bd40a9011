"""Long work on a pipe says how far it has come: `ros-interfaces install` (each package's build
steps), `ros-interfaces generate` and `lcm-types generate` (the types written). A pipe hears
nothing of work shorter than `QUIET_S` (2 s); it is 0 here, so that what is said does not depend
on how busy the machine is."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.lcmcodec.corpus import CORPUS
from viewer_bridge.cli.main import main
from viewer_bridge.ros_build import interfaces as ros_interfaces
from viewer_bridge.util import progress as progress_module

PACKAGE = "vbtest_progress_lcm_msgs"  # built by this file alone, removed first each time


@pytest.fixture(autouse=True)
def no_quiet_seconds(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(progress_module, "QUIET_S", 0.0)


def _shares(lines: list[str], start: str, pattern: str) -> list[int]:
    """The percentages of the progress lines that start with `start` (each must match
    `start` + `NN%: ` + `pattern` + ` (N s)`)."""
    said = [line for line in lines if line.startswith(start)]
    for line in said:
        assert re.fullmatch(re.escape(start) + r"\d+%: " + pattern + r" \(\d+ s\)", line), line
    return [int(line[len(start) :].split("%")[0]) for line in said]


def test_ros_interfaces_generate_says_how_many_types_it_has_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["ros-interfaces", "generate", "--lcm-types", str(CORPUS), "-o", str(tmp_path)]) == 0
    lines = capsys.readouterr().err.splitlines()
    total = sum(len(list(folder.glob("msg/*.msg"))) for folder in tmp_path.iterdir())
    shares = _shares(lines, "viewer-bridge ros-interfaces: writing: ", rf"\d+ of {total} types")
    assert shares == sorted(set(shares)) and shares[-1] == 100 and len(shares) >= 5
    assert lines[-1].startswith("viewer-bridge ros-interfaces: wrote ")  # each package's line after


def test_lcm_types_generate_says_how_many_types_it_has_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["lcm-types", "generate", "--ros-types", "geometry_msgs", "-o", str(tmp_path)]) == 0
    lines = capsys.readouterr().err.splitlines()
    total = len(list(tmp_path.rglob("*.lcm")))
    shares = _shares(lines, "viewer-bridge lcm-types: writing: ", rf"\d+ of {total} types")
    assert shares == sorted(set(shares)) and shares[-1] == 100 and len(shares) >= 5
    assert lines[-1] == f"viewer-bridge lcm-types: wrote {total} types into {tmp_path}"


def test_ros_interfaces_install_says_how_far_each_package_build_has_come(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "sample_t.lcm").write_text(
        "package vbtest_progress;\nstruct sample_t { int64_t utime; double x; }\n"
    )
    ros_interfaces.uninstall([PACKAGE])  # built by an earlier run: built again
    assert main(["ros-interfaces", "install", PACKAGE, "--yes", "--lcm-types", str(tmp_path)]) == 0
    lines = capsys.readouterr().err.splitlines()
    start = f"viewer-bridge ros-interfaces: building {PACKAGE}: "
    shares = _shares(lines, start, r"\d+ of \d+ build steps")
    assert shares == sorted(set(shares)) and shares[-1] == 100 and len(shares) >= 5
    assert lines[0].startswith(f"building {PACKAGE} (1 type) into ")
    assert re.fullmatch(rf"built {PACKAGE} in \d+\.\d s", lines[-1])
    assert lines.index(next(line for line in lines if line.startswith(start))) > 0
