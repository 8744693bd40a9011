"""A core-only Python, made from the full venv: importing a peer the core does not need fails.

Put this folder first on PYTHONPATH (Python imports `sitecustomize` at start-up) to run tests as
they would run where only the core is installed: rclpy and the ROS 2 interface packages, pydrake
(and Drake's `drake` LCM types), foxglove, zenoh and moderngl raise `ModuleNotFoundError`, as
when they are absent. `tests/test_core_only.py` runs the codec tests this way:

    VIEWER_BRIDGE_CORE_ONLY=1 PYTHONPATH=tests/core_only:. python -m pytest tests/formats

(VIEWER_BRIDGE_CORE_ONLY=1 lets tests that need a peer skip; everywhere else a skip fails the run.)
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType

BLOCKED = {
    "rclpy",
    "rpyutils",
    "pydrake",
    "drake",
    "foxglove",
    "foxglove_schemas_protobuf",
    "zenoh",
    "moderngl",
}


def blocked(name: str) -> bool:
    """Whether `name` (a module's full name) is one of the peers a core install lacks."""
    top = name.partition(".")[0]
    return top in BLOCKED or top.endswith(("_msgs", "_interfaces")) or top.startswith(("rosidl", "rmw"))


class _Absent(importlib.abc.MetaPathFinder):
    """Refuses a blocked module installed in the environment; one elsewhere (the tests' own
    lcm-gen output, a `drake` package of generated classes) is found as usual."""

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if not blocked(fullname):
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        origin = (spec.origin or "") if spec is not None else ""
        locations = list(spec.submodule_search_locations or []) if spec is not None else []
        if spec is None or any(part in where for where in (origin, *locations) for part in _INSTALLED):
            raise ModuleNotFoundError(f"No module named {fullname!r} (core-only run)", name=fullname)
        return spec


_INSTALLED = ("site-packages", "dist-packages")


sys.meta_path.insert(0, _Absent())
