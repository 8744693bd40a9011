"""The API reference (mkdocs.yml, docs/): built from the docstrings with `--strict`, so that a
broken link, a page left out of the nav or a docstring mkdocstrings cannot read fails the run."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_api_reference_builds_without_warnings(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "WARNING" not in result.stderr, result.stderr
    convert_page = (tmp_path / "site/api/convert/index.html").read_text()
    for name in ("draw_to_pose_array", "draw_to_tree_viewer", "load_to_marker_array", "pose_array_to_draw"):
        assert f'id="viewer_bridge.convert.{name}"' in convert_page
    streams_page = (tmp_path / "site/api/streams/index.html").read_text()
    assert 'id="viewer_bridge.formats.drake.draw.DrawDecoder.decode"' in streams_page
