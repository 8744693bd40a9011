"""Advice said once per machine, not on every run: a hint that holds until the user changes the
machine (raise a kernel limit, say) is worth one reading. Each is remembered by a marker file under
the user's cache folder (`$XDG_CACHE_HOME/viewer-bridge/hints/`, else `~/.cache/...`); `--debug`
(`DEBUG_ENV`, which the command line sets and worker processes inherit) says every hint again.
"""

from __future__ import annotations

import os
from pathlib import Path

DEBUG_ENV = "VIEWER_BRIDGE_DEBUG"


def hints_folder() -> Path:
    """Where the markers of the hints already given are kept."""
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "viewer-bridge" / "hints"


def first_time(hint: str) -> bool:
    """Whether to give `hint` (a file name) now: never given on this machine, or under `--debug`.
    Marked as given from now on; a cache folder that cannot be written is no reason to keep quiet."""
    if os.environ.get(DEBUG_ENV):
        return True
    marker = hints_folder() / hint
    if marker.exists():
        return False
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.touch()
    except OSError:
        pass
    return True
