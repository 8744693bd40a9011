"""The examples by name (`EXAMPLES`), whether Drake is here to run them, and running one.

Imports no pydrake: an example's module (`viewer_bridge.examples.<name>`) is imported when it runs.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable
from typing import cast

INSTALL_HINT = "pip install 'viewer-bridge[drake]'"

# name -> what it publishes (the module viewer_bridge.examples.<name> has `run(url, seconds)`).
EXAMPLES = {
    "shapes": "every Drake shape in two model instances falling onto the ground, in the illustration, "
    "proximity and perception roles (DRAKE_VIEWER_*_<ROLE>)",
    "cameras": "two simulated RGB-D cameras, colour, depth and labels (DRAKE_RGBD_CAMERA_IMAGES_<name>)",
    "contacts": "a box (point contact) and a sphere (hydroelastic surface) on the ground "
    "(DRAKE_VIEWER_*, CONTACT_RESULTS)",
    "point_cloud": "a turning, coloured ring of points (DRAKE_POINT_CLOUD_EXAMPLE)",
}


def drake_missing() -> str | None:
    """Why the examples cannot run here (Drake is not installed), or None."""
    if importlib.util.find_spec("pydrake") is None:
        return f"the examples simulate with Drake, which is not installed: {INSTALL_HINT}"
    return None


def run_example(name: str, url: str, seconds: float) -> None:
    """Run example `name`, publishing on the LCM `url` for `seconds` of simulated (and real) time."""
    module = importlib.import_module(f"viewer_bridge.examples.{name}")
    cast(Callable[[str, float], None], module.run)(url, seconds)
