"""Peers some tests need and a core-only install lacks (rclpy and ROS 2 interfaces, pydrake and
Drake's LCM types, foxglove): imported on first use, inside the test that uses them.

`drake_lcmtypes = peer("drake")` at a module's top imports nothing; `drake_lcmtypes.lcmt_viewer_draw`
in a test imports Drake's package then, through `pytest.importorskip`: where it is absent, that test
is skipped and the module's other tests (the codecs') still run. A skip fails the run unless
VIEWER_BRIDGE_CORE_ONLY=1 (tests/conftest.py): in `./dev test` every peer is installed.
"""

from __future__ import annotations

from typing import Any

import pytest


class peer:  # noqa: N801 - used like an import statement
    """A module imported on first attribute access, skipping the test when it is absent."""

    def __init__(self, name: str) -> None:
        self._name = name

    def __getattr__(self, attribute: str) -> Any:
        if attribute.startswith("_"):  # pytest's collection looks for its own markers: not a use
            raise AttributeError(attribute)
        return getattr(pytest.importorskip(self._name), attribute)
