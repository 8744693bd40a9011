"""The wheel as a user installs it: built from this checkout (`python -m build`), installed into a
fresh venv outside it, run from a folder that is not the checkout (and with no PYTHONPATH), so
that nothing of the checkout can be imported by mistake.

With the core only, the README's library snippet runs (draw bytes -> PoseArray CDR and the
tree viewer's request) and gives what this checkout gives, without importing any optional
part; a transport whose extra is missing is refused in one line naming it. With `[all]`,
the command line runs the bridge on its demo as `./dev run` does.

Each extra alone (tests/extras_table.py's rows, which `python -m tests.extras_table` prints as a
table): a copy of the core venv, that one extra installed from the same wheel, its headline
command run. The core venv itself is never changed: what installs more works on a copy. The
library guide (docs/library.md) runs top to bottom on the core install, and `ros-interfaces
install` refuses there to pip install the ROS 2 wheels unasked.
"""

from __future__ import annotations

import json
import re
import subprocess
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests import extras_table
from tests.conftest import lcm_url
from tests.extras_table import run
from tests.test_docs import blocks, substituted
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


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return extras_table.build_wheel(tmp_path_factory.mktemp("dist"))


@pytest.fixture(scope="module")
def venv(tmp_path_factory: pytest.TempPathFactory, wheel: Path) -> Path:
    """A fresh venv with the wheel's core install (no extra); never changed (see `copy`)."""
    return extras_table.core_venv(tmp_path_factory.mktemp("venv"), wheel)


def copy(venv: Path, tmp_path: Path) -> Path:
    """A copy of the core venv to install more into (run it as `python -m viewer_bridge`: its
    console scripts name the core venv's interpreter)."""
    return extras_table.clone(venv, tmp_path / "env")


def test_the_wheel_ships_the_type_marker_and_the_data(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    for name in (
        "viewer_bridge/py.typed",
        "viewer_bridge/convert.py",
        "viewer_bridge/_data/lcmtypes/lcmt_viewer_draw.lcm",
    ):
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
    refused = run(
        [str(venv / "bin/viewer-bridge"), "run", "-c", "builtin:foxglove", "--duration", "1"], tmp_path
    )
    assert refused.returncode == 2, refused.stderr
    assert "pip install 'viewer-bridge[foxglove]'" in refused.stderr and "Traceback" not in refused.stderr


@pytest.mark.timeout(3000)  # and then every extra installed, and tf2_msgs compiled
def test_the_bridge_runs_its_demo_with_every_extra(venv: Path, wheel: Path, tmp_path: Path) -> None:
    env = copy(venv, tmp_path)
    installed = run([str(env / "bin/python"), *extras_table.PIP_INSTALL, f"{wheel}[all]"], tmp_path)
    assert installed.returncode == 0, installed.stderr
    cli = str(env / "bin/python"), "-m", "viewer_bridge"
    version = run([*cli, "--version"], tmp_path)
    assert version.stdout.startswith("viewer-bridge "), version
    # tf2_msgs, as ./dev run builds it
    interfaces = run([*cli, "ros-interfaces", "install", "--yes"], tmp_path)
    assert interfaces.returncode == 0, interfaces.stderr
    # ROS 2 traffic stays on this host, in this test process's domain (tests/conftest.py sets both).
    # Six seconds: on a loaded machine the demo's first draws may take a few to arrive.
    demo = run([*cli, "run", "--demo", "--duration", "6", "--lcm-url", lcm_url(41), "--set", "foxglove.port=0"],
               tmp_path, timeout=300)  # fmt: skip
    assert demo.returncode == 0, demo.stderr
    assert "Traceback" not in demo.stderr
    assert " route poses: " in demo.stderr, demo.stderr


OUTCOMES: list[extras_table.Outcome] = []


@pytest.fixture(scope="module", autouse=True)
def the_table() -> Iterator[None]:
    """The rows' table, printed once they ran (`pytest -s` shows it; `python -m tests.extras_table`
    prints the same for every row)."""
    yield
    if OUTCOMES:
        print("\n" + extras_table.table(OUTCOMES))


def test_every_extra_has_a_row() -> None:
    """A new extra in pyproject.toml gets a row (a headline command), or a reason in NOT_ALONE."""
    assert set(extras_table.ROWS) - {""} == set(extras_table.extras()) - set(extras_table.NOT_ALONE)


@pytest.mark.parametrize("extra", list(extras_table.ROWS), ids=[name or "core" for name in extras_table.ROWS])
@pytest.mark.timeout(3000)  # ros-build: pip installs rclpy's wheels and compiles tf2_msgs
def test_one_extra_alone_runs_its_headline_command(
    extra: str, venv: Path, wheel: Path, tmp_path: Path
) -> None:
    row = extras_table.ROWS[extra]
    outcome = extras_table.try_extra(row, wheel, venv, tmp_path, lcm_url(45))
    OUTCOMES.append(outcome)
    assert outcome.ok, (
        f"{outcome.step.shown() if outcome.step else ''} exited {outcome.code}:\n{outcome.output[-4000:]}"
    )
    if extra:  # the extra's own distributions, and no other extra's
        assert set(outcome.direct) <= set(outcome.added), outcome.added
        others = {name for other, requirements in extras_table.extras().items() if other not in (extra, "all", "test")
                  for name in extras_table.requirement_names(requirements)} - set(outcome.direct)  # fmt: skip
        assert not others & set(outcome.added), others & set(outcome.added)


def test_the_library_guide_runs_on_the_core_install(venv: Path, tmp_path: Path) -> None:
    """docs/library.md's Python, top to bottom, where no extra is installed, in a folder with the
    demo's log as the page says to write it; what needs `[ros]` says so as MissingExtra."""
    python = str(venv / "bin/python")
    demo = run(
        [python, "-m", "viewer_bridge", "demo", "--url", "file://demo.lcmlog?mode=w", "--duration", "1"],
        tmp_path,
    )
    assert demo.returncode == 0, demo.stderr
    page = (ROOT / "docs" / "library.md").read_text()
    assert "viewer-bridge demo --url 'file://demo.lcmlog?mode=w' --duration 1" in page
    script = tmp_path / "library.py"
    script.write_text("\n".join(substituted(block) for block in blocks(page, ("python",))))
    result = run([python, str(script)], tmp_path, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]
    assert (
        "to_rclpy needs visualization_msgs, not installed: pip install 'viewer-bridge[ros]'\n"
        in result.stdout
    )
    assert "ModuleNotFoundError" not in result.stderr and "Traceback" not in result.stderr, result.stderr
    assert run([python, "-c", "import rclpy"], tmp_path).returncode != 0  # no extra there indeed


def test_ros_interfaces_install_never_pip_installs_unasked(venv: Path, tmp_path: Path) -> None:
    """Where rclpy is missing, `ros-interfaces install` from a script (no terminal) refuses in one
    line naming --yes, and the venv is as it was."""
    env = copy(venv, tmp_path)
    before = extras_table.distributions(env)
    refused = subprocess.run(
        [str(env / "bin/python"), "-m", "viewer_bridge", "ros-interfaces", "install"], cwd=tmp_path,
        env=extras_table.clean_env(), stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert refused.returncode == 2, refused.stderr
    assert refused.stderr.startswith(
        "viewer-bridge ros-interfaces: building needs pip install ros-jazzy-rclpy "
    )
    assert refused.stderr.endswith(
        ": run again with --yes to allow it, or pip install 'viewer-bridge[ros,ros-build]' first\n"
    )
    assert refused.stderr.count("\n") == 1
    assert extras_table.distributions(env) == before
    assert not (env / "share" / "tf2_msgs").exists()
