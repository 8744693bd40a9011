"""The wheel as a user installs it: built from this checkout (`python -m build`), installed into a
fresh venv outside it, run from a folder that is not the checkout (and with no PYTHONPATH), so
that nothing of the checkout can be imported by mistake.

With the core only, the README's library snippet runs (draw bytes -> PoseArray CDR and the
tree viewer's request) and gives what this checkout gives, without importing any optional
part; a transport whose extra is missing is refused in one line naming it. With `[all]`,
the command line runs the bridge on its demo as `./dev run` does.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from tests.conftest import lcm_url
from tests.test_docs import blocks
from viewer_bridge import convert
from viewer_bridge.examples.demo import demo_poses, demo_scene
from viewer_bridge.formats.drake.draw import DrawEncoder

# Building the wheel and installing it into a fresh venv may each take up to 900 s.
pytestmark = [pytest.mark.slow, pytest.mark.timeout(2000)]
ROOT = Path(__file__).resolve().parents[1]
HEAVY = ["rclpy", "moderngl", "foxglove", "foxglove_schemas_protobuf", "zenoh", "zmq", "trimesh", "scipy"]

# The README block's input, made with the installed package: the log its tour records
# (`viewer-bridge demo --url 'file://demo.lcmlog?mode=w'`), here a load and one draw of the demo.
SETUP = """
from viewer_bridge.examples.demo import demo_poses, demo_scene
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.transports.lcm import LcmEvent, write_log
write_log("demo.lcmlog", [
    LcmEvent("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(demo_scene()).encode(), 0),
    LcmEvent("DRAKE_VIEWER_DRAW", DrawEncoder().encode(demo_poses(demo_scene(), 1.0)), 1),
])
"""
REPORT = f"""
import json, sys, viewer_bridge
print(json.dumps({{"file": viewer_bridge.__file__, "pose_array": pose_array.hex(), "request": request,
                   "heavy": [name for name in {HEAVY!r} if name in sys.modules]}}))
"""


def library_snippet() -> str:
    """The first Python block of README's Library section."""
    text = (ROOT / "README.md").read_text()
    section = text[text.index("\n## Library\n") :]
    section = section.split("\n## ", 2)[1]  # up to the next section, if any
    return blocks(section, ("python",))[0]


# No check for a newer pip (a request to PyPI). Byte-compiling stays: skipped (--no-compile, a sixth
# of the install's time), the first `run --demo` compiles numpy and the rest as it imports them,
# and on a loaded machine its 2 s window then carried no draw.
PIP_QUICK = ["--quiet", "--disable-pip-version-check"]


def clean_env() -> dict[str, str]:
    """This process's environment without what points at the checkout or its venv."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}


def run(command: list[str], cwd: Path, timeout: float = 900, **env: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        command, cwd=cwd, env={**clean_env(), **env}, capture_output=True, text=True, timeout=timeout, check=False
    )


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    # --no-isolation: the build backend (hatchling, in the test extra) is already installed.
    built = run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(out), str(ROOT)], out)
    assert built.returncode == 0, built.stderr
    (path,) = out.glob("viewer_bridge-*.whl")
    return path


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory, wheel: Path) -> Path:
    """A fresh venv with the wheel's core install (no extra)."""
    root = tmp_path_factory.mktemp("venv")
    created = run([sys.executable, "-m", "venv", str(root / "env")], root)
    assert created.returncode == 0, created.stderr
    installed = run([str(root / "env/bin/python"), "-m", "pip", "install", *PIP_QUICK, str(wheel)], root)
    assert installed.returncode == 0, installed.stderr
    return root / "env"


def test_the_wheel_ships_the_type_marker_and_the_data(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    for name in ("viewer_bridge/py.typed", "viewer_bridge/convert.py", "viewer_bridge/_data/lcmtypes/lcmt_viewer_draw.lcm"):
        assert name in names
    assert not any(name.startswith("tests/") for name in names)


def test_the_readme_snippet_runs_on_the_core_install(venv: Path, tmp_path: Path) -> None:
    result = run([str(venv / "bin/python"), "-c", SETUP + library_snippet() + REPORT], tmp_path)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert Path(report["file"]).is_relative_to(venv)  # the installed package, not the checkout
    assert report["heavy"] == []
    draw_bytes = DrawEncoder().encode(demo_poses(demo_scene(), 1.0))
    assert bytes.fromhex(report["pose_array"]) == convert.draw_to_pose_array(draw_bytes)
    assert report["request"] == json.loads(json.dumps(convert.draw_to_tree_viewer(draw_bytes)))


def test_a_missing_extra_is_one_line_naming_it(venv: Path, tmp_path: Path) -> None:
    version = run([str(venv / "bin/viewer-bridge"), "--version"], tmp_path)
    assert version.returncode == 0 and re.fullmatch(r"viewer-bridge \d+\.\d+\.\d+\n", version.stdout), version
    refused = run([str(venv / "bin/viewer-bridge"), "run", "-c", "builtin:foxglove", "--duration", "1"], tmp_path)
    assert refused.returncode == 2, refused.stderr
    assert "pip install 'viewer-bridge[foxglove]'" in refused.stderr and "Traceback" not in refused.stderr


@pytest.mark.timeout(3000)  # and then every extra installed, and tf2_msgs compiled
def test_the_bridge_runs_its_demo_with_every_extra(venv: Path, wheel: Path, tmp_path: Path) -> None:
    installed = run([str(venv / "bin/python"), "-m", "pip", "install", *PIP_QUICK, f"{wheel}[all]"], tmp_path)
    assert installed.returncode == 0, installed.stderr
    cli = str(venv / "bin/viewer-bridge")
    version = run([cli, "--version"], tmp_path)
    assert version.stdout.startswith("viewer-bridge "), version
    interfaces = run([cli, "ros-interfaces", "install"], tmp_path)  # tf2_msgs, as ./dev run builds it
    assert interfaces.returncode == 0, interfaces.stderr
    # ROS 2 traffic stays on this host, in this test process's domain (tests/conftest.py sets both).
    demo = run([cli, "run", "--demo", "--duration", "2", "--lcm-url", lcm_url(41)], tmp_path, timeout=120)
    assert demo.returncode == 0, demo.stderr
    assert "Traceback" not in demo.stderr
    assert " route poses: " in demo.stderr, demo.stderr
