"""Drake's stream, shared by every route: a draw is decoded once however many translators read it."""

from __future__ import annotations

from typing import Any

import pytest

from viewer_bridge.examples.scenes import draw_of, small_scene
from viewer_bridge.formats.drake.draw import DrawDecoder
from viewer_bridge.formats.drake.load import load_from_scene
from viewer_bridge.translators import TRANSLATORS, LoadCache
from viewer_bridge.translators.types import LOAD_TYPE
from viewer_bridge.transports.base import Received


def test_a_draw_read_by_several_translators_is_decoded_once(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    decode = DrawDecoder.decode

    def counting(self: DrawDecoder, data: Any) -> Any:
        calls.append(len(data))
        return decode(self, data)

    monkeypatch.setattr(DrawDecoder, "decode", counting)
    scene = small_scene()
    loads = LoadCache()
    names = ["drake_to_marker_array", "drake_to_pose_array", "drake_to_clock", "drake_to_ign_pose_v"]
    translators = [TRANSLATORS.get(name)({}, loads) for name in names]
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
