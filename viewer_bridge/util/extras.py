"""The optional parts of viewer-bridge, and the one error a missing one raises.

The core install (`pip install viewer-bridge`) is what the pure converters of
`viewer_bridge.convert` need. Transports, the render server and a few converters need more;
each such dependency belongs to one extra of `pyproject.toml`, listed in `EXTRAS`. Code that
needs one imports it through `require` (or turns its `ImportError` into `missing`), so that a
user without it reads one line naming the pip command, as a `MissingExtra`.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from viewer_bridge.errors import MissingExtra

# Top-level module -> the extra that installs it.
EXTRAS: dict[str, str] = {
    "rclpy": "ros",
    "geometry_msgs": "ros",
    "sensor_msgs": "ros",
    "shape_msgs": "ros",
    "visualization_msgs": "ros",
    "foxglove": "foxglove",
    "foxglove_schemas_protobuf": "foxglove",
    "mcap": "foxglove",
    "zmq": "ign",
    "zenoh": "zenoh",
    "xxhash": "zenoh",
    "moderngl": "render",
    "rerun": "rerun",
    "pyarrow": "rerun",
}


# The built-in transports that need an extra -> that extra (a transport of the core or a plugin's: none).
TRANSPORT_EXTRAS: dict[str, str] = {
    "ros": "ros",
    "foxglove": "foxglove",
    "mcap": "foxglove",
    "zenoh": "zenoh",
    "rerun": "rerun",
    "ign": "ign",
}


def lacking(transport: str) -> str | None:
    """The first module `transport` needs that is not installed (its extra's, `EXTRAS`), or None."""
    extra = TRANSPORT_EXTRAS.get(transport)
    return next(
        (module for module, owner in EXTRAS.items() if owner == extra and not importable(module)), None
    )


def importable(module: str) -> bool:
    """Whether `module` can be found (one made missing, `sys.modules[name] = None`, counts as absent)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def missing(error: ImportError, needed_by: str) -> MissingExtra:
    """The `MissingExtra` for an `ImportError` of a module in `EXTRAS` (`all` for any other)."""
    module = (error.name or "").partition(".")[0] or "an optional module"
    return MissingExtra(needed_by, module, EXTRAS.get(module, "all"))


def require(module: str, needed_by: str) -> ModuleType:
    """`import module`, or `MissingExtra` naming its extra when it is not installed."""
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise missing(error, needed_by) from None


__all__ = ["EXTRAS", "TRANSPORT_EXTRAS", "importable", "lacking", "missing", "require"]
