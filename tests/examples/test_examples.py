"""`viewer-bridge example NAME`: each example simulation records what Drake publishes, through
LCM's own `file://LOG?mode=w`; without Drake, one line names the install."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from viewer_bridge.examples.catalog import EXAMPLES, INSTALL_HINT
from viewer_bridge.transports.lcm import read_log

pytestmark = pytest.mark.slow

# What each example's recording must hold: a channel regex and how many messages at least.
EXPECTED = {
    "shapes": {f"DRAKE_VIEWER_{kind}_{role}": least for kind, least in (("LOAD_ROBOT", 1), ("DRAW", 5))
               for role in ("ILLUSTRATION", "PROXIMITY", "PERCEPTION")},
    "cameras": {"DRAKE_RGBD_CAMERA_IMAGES_left": 1, "DRAKE_RGBD_CAMERA_IMAGES_right": 1},
    "contacts": {"DRAKE_VIEWER_LOAD_ROBOT": 1, "DRAKE_VIEWER_DRAW": 5, "CONTACT_RESULTS": 5},
    "point_cloud": {"DRAKE_POINT_CLOUD_EXAMPLE": 3},
}  # fmt: skip


def test_every_example_is_checked() -> None:
    assert set(EXPECTED) == set(EXAMPLES)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_an_example_records_its_messages(name: str, tmp_path: Path) -> None:
    log = tmp_path / f"{name}.lcmlog"
    done = subprocess.run(
        [sys.executable, "-m", "viewer_bridge.cli.main", "example", name, "--duration", "0.5", "--lcm-url",
         f"file://{log}?mode=w"], capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    channels = [event.channel for event in read_log(log)]
    for channel, least in EXPECTED[name].items():
        assert channels.count(channel) >= least, (channel, sorted(set(channels)))


def test_without_drake_one_line_names_the_install() -> None:
    code = "import sys; sys.modules['pydrake'] = None; from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))"
    done = subprocess.run(
        [sys.executable, "-c", code, "example", "shapes"], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2 and not done.stdout
    assert done.stderr.splitlines() == [
        f"viewer-bridge example: the examples simulate with Drake, which is not installed: {INSTALL_HINT}"
    ]
