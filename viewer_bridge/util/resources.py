"""Where the project's data folders (`lcmtypes/`, `mappings/`) are found at run time.

A wheel carries them inside the package as `viewer_bridge/_data/<name>`; a source checkout or an
editable install reads them from the repository root, so there is only ever one copy.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]  # viewer_bridge/, above this util/ folder


def data_dir(name: str) -> Path:
    """The folder `name` (e.g. "lcmtypes"), from the installed package or the checkout."""
    for candidate in (_PACKAGE / "_data" / name, _PACKAGE.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"viewer-bridge data folder {name!r} is missing from the installation")
