"""Drake's stream, shared by every route: a draw is decoded once however many translators read it."""

from __future__ import annotations

from typing import Any

import pytest

from viewer_bridge.errors import NotGiven
from viewer_bridge.examples.scenes import draw_of, small_scene
from viewer_bridge.formats.drake.draw import DrawDecoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.shared import Shared
from viewer_bridge.translators.load_cache import LoadCache
from viewer_bridge.translators.registry import TRANSLATORS
from viewer_bridge.translators.types import LOAD_TYPE
from viewer_bridge.transports.base import Received
from viewer_bridge.transports.playback import Timelines


def test_a_draw_read_by_several_translators_is_decoded_once(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    decode = DrawDecoder.decode

    def counting(self: DrawDecoder, data: Any) -> Any:
        calls.append(len(data))
        return decode(self, data)

    monkeypatch.setattr(DrawDecoder, "decode", counting)
    scene = small_scene()
    shared = Shared(given=[LoadCache()])  # one router's
    names = ["drake_to_marker_array", "drake_to_pose_array", "drake_to_clock", "drake_to_ign_pose_v"]
    translators = [TRANSLATORS.get(name)({}, shared=shared) for name in names]
    load = Received("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode())
    for translator in translators:
        translator.observe(load)
        if LOAD_TYPE in translator.reads:
            translator.translate(load)
    draw = Received("DRAKE_VIEWER_DRAW", draw_of(scene, 1.0))
    outputs = [translator.translate(draw) for translator in translators]
    assert calls == [len(draw.data)]  # four translators, one decode
    assert all(len(out) == 1 for out in outputs)
    again = Received("DRAKE_VIEWER_DRAW", draw_of(scene, 2.0))  # the next message is decoded anew
    translators[1].translate(again)
    assert len(calls) == 2


def test_two_routers_share_no_load_and_no_decode() -> None:
    scene = small_scene()
    load = Received("DRAKE_VIEWER_LOAD_ROBOT", load_from_scene(scene).encode())
    draw = Received("DRAKE_VIEWER_DRAW", draw_of(scene, 1.0))
    first, second = Shared(given=[LoadCache()]), Shared(given=[LoadCache()])  # two routers in one process
    a = TRANSLATORS.get("drake_to_marker_array")({}, shared=first)
    b = TRANSLATORS.get("drake_to_marker_array")({}, shared=second)
    same_router = TRANSLATORS.get("drake_to_shapes")({}, shared=first)
    a.observe(load)
    assert first.given(LoadCache).get("DRAKE_VIEWER_LOAD_ROBOT") == load.data
    assert second.given(LoadCache).get("DRAKE_VIEWER_LOAD_ROBOT") is None
    assert b.translate(draw) == []  # its router never saw the load: no scene to publish
    assert same_router.translate(draw) != []  # its router's cache brings the scene
    assert a.draw_poses is same_router.draw_poses and a.draw_poses is not b.draw_poses
    assert b.draw_poses(draw) is not a.draw_poses(draw)  # each router decodes for itself


def test_a_shared_gives_only_what_it_was_given() -> None:
    """What a router's config decides is given when its `Shared` is made, never guessed: a Drake
    translator made with a `Shared` given no load cache says so at once, naming the kind."""
    cache = LoadCache()
    shared = Shared(given=[cache])
    assert shared.given(LoadCache) is cache
    with pytest.raises(NotGiven, match=r"^this Shared was given no LoadCache when it was made"):
        TRANSLATORS.get("drake_to_marker_array")({}, shared=Shared())
    with pytest.raises(NotGiven, match="no Timelines"):
        shared.given(Timelines)
    alone = TRANSLATORS.get("drake_to_marker_array")({})  # made alone: a Shared of its own, loads in memory
    assert alone.shared.given(LoadCache) is not cache
