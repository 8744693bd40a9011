"""viewer-bridge: Drake's LCM viewer messages to ROS 2, ign/gz, Director's tree viewer, Foxglove
and glTF, and back.

- `viewer_bridge.convert`: pure converters, one message per call
  (`convert.draw_to_pose_array(draw_bytes)`).
- `viewer_bridge.streams`: the same conversions for streams of messages, faster per message.
- `viewer_bridge.lcm_types(*sources)`: a store of LCM types (yours, the project's, Drake's):
  decode and encode, to and from CDR and dicts.
- `viewer_bridge.errors`: every error raised on purpose, under `BridgeError`.

Importing this package imports nothing else: each of those modules is imported when named.
"""

from __future__ import annotations

import importlib
from typing import Any

_SUBMODULES = ("convert", "errors", "streams")


def __getattr__(name: str) -> Any:
    """`viewer_bridge.convert` and its siblings imported on first use, and `__version__` read from
    the installed distribution's metadata then (PEP 562): importing the package costs nothing."""
    if name in _SUBMODULES:
        return importlib.import_module(f"viewer_bridge.{name}")
    if name == "lcm_types":  # a function: its module is `typestore`
        return importlib.import_module("viewer_bridge.typestore").lcm_types
    if name == "__version__":
        from importlib.metadata import PackageNotFoundError, version

        try:
            return version("viewer-bridge")
        except PackageNotFoundError:  # run from a checkout that is not installed
            return "0+unknown"
    raise AttributeError(f"module 'viewer_bridge' has no attribute {name!r}")


__all__ = ["__version__", "convert", "errors", "lcm_types", "streams"]
