"""The corpus library and lcm-gen's classes for it, shared by the codec tests (lcm-gen runs once)."""

from __future__ import annotations

import pytest

from tests.lcmcodec.corpus import CORPUS, generate_lcmgen
from viewer_bridge.lcmcodec import layout
from viewer_bridge.lcmcodec.library import TypeLibrary


@pytest.fixture(scope="module")
def library() -> TypeLibrary:
    return TypeLibrary.load([str(CORPUS)])


@pytest.fixture(scope="session")
def classes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, type]:
    return generate_lcmgen(tmp_path_factory.mktemp("corpus_lcmgen"))


@pytest.fixture(params=["compiled", "python"])
def mover(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """The kept layouts' mover a test runs on: the compiled one (`_mover.c`), or the Python ones
    (one `struct` pair, a numpy gather) that a package built without a compiler uses."""
    if request.param == "python":
        monkeypatch.setattr(layout, "COMPILED_MOVER", False)
    return str(request.param)
