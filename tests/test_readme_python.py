"""Every ```python block of README.md, run as a reader would run them: top to bottom, in one
session, each block after the ones above it (a block may use what an earlier one defined).

The session starts with two names the blocks take as given, the bytes a user's LCM subscriber
or log would hand them: `load_bytes`, the demo scene's `lcmt_viewer_load_robot` (every Drake
shape, two model instances), and `draw_bytes`, one of its draws. LCM traffic (the tree viewer
block publishes) goes to this test's own bus: `LCM_DEFAULT_URL` is a ttl=0 URL. Nothing else
of the README's code is changed. The command lines are run by tests/test_readme_commands.py.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import lcm_url
from viewer_bridge.demo import demo_poses, demo_scene
from viewer_bridge.formats.drake.draw import DrawEncoder
from viewer_bridge.formats.drake.load import load_from_scene

README = Path(__file__).parents[1] / "README.md"


def python_blocks(text: str) -> list[tuple[int, str]]:
    """(line number of the block's first line, its code) for each ```python block, in order."""
    return [
        (text.count("\n", 0, match.start(1)) + 1, match.group(1))
        for match in re.finditer(r"^```python\n(.*?)^```", text, flags=re.MULTILINE | re.DOTALL)
    ]


def session() -> dict[str, Any]:
    """What the blocks start from: a load's and a draw's bytes."""
    scene = demo_scene()
    return {
        "__name__": "__readme__",
        "load_bytes": load_from_scene(scene).encode(),
        "draw_bytes": DrawEncoder().encode(demo_poses(scene, 1.0)),
    }


BLOCKS = python_blocks(README.read_text())


def test_the_readme_has_python_blocks() -> None:
    assert len(BLOCKS) >= 5  # Library (2), Translators (ROS 2, ign, tree viewer)


@pytest.mark.parametrize("count", range(1, len(BLOCKS) + 1), ids=[f"README.md:{line}" for line, _ in BLOCKS])
def test_a_readme_block_runs_after_the_ones_above_it(count: int, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LCM_DEFAULT_URL", lcm_url(40))
    namespace = session()
    for line, code in BLOCKS[:count]:
        # Compiled with the README's line numbers, so a failure's traceback points into README.md.
        exec(compile("\n" * (line - 1) + code, str(README), "exec"), namespace)


def test_the_library_snippet_gives_pose_array_cdr_and_the_tree_viewer_request() -> None:
    namespace = session()
    exec(BLOCKS[0][1], namespace)
    assert namespace["pose_array"][:4] == b"\x00\x01\x00\x00"  # little-endian CDR
    assert len(namespace["request"]["settransform"]) == len(demo_poses(demo_scene(), 1.0))
