"""Where `--workers N` puts each route (`viewer_bridge.router.workers.place`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from viewer_bridge.config.bridge import BridgeConfig, load_config
from viewer_bridge.errors import ConfigError, UsageError
from viewer_bridge.router.workers import place


def relay(name: str, source: str, worker: int | None = None, destination: str = "lcm") -> dict[str, object]:
    route: dict[str, object] = {
        "name": name, "source": {"transport": "lcm", "name": source}, "translator": "lcm_relay",
        "destination": {"transport": destination, "name": f"{name}_OUT"},
    }  # fmt: skip
    return route if worker is None else {**route, "worker": worker}


def placed(config: BridgeConfig, workers: int) -> list[list[str]]:
    return [[route.name for route in routes] for routes in place(config, workers)]


def test_routes_of_one_source_stay_together_and_groups_go_to_the_least_loaded_worker() -> None:
    config = BridgeConfig.model_validate({"routes": [
        relay("a1", "A"), relay("b", "B"), relay("a2", "A"), relay("c", "C"), relay("d", "D"),
    ]})  # fmt: skip
    assert placed(config, 2) == [["a1", "a2", "d"], ["b", "c"]]
    assert placed(config, 3) == [["a1", "a2"], ["b", "d"], ["c"]]
    assert placed(config, 1) == [["a1", "a2", "b", "c", "d"]]


def test_a_pinned_route_runs_where_it_says_and_counts_for_the_balance() -> None:
    config = BridgeConfig.model_validate(
        {"routes": [relay("a", "A", worker=1), relay("b", "B"), relay("c", "C")]}
    )
    assert placed(config, 2) == [["b", "c"], ["a"]]  # b: a tie, the lower index
    with pytest.raises(UsageError, match="route a: worker: 1, but the bridge runs 1 worker"):
        place(config, 1)


def test_a_route_through_a_transport_only_one_process_may_open_stays_on_worker_0() -> None:
    # A Zenoh session may listen on a port of its own: the route is not spread.
    config = BridgeConfig.model_validate({"routes": [relay("a", "A"), relay("z", "Z", destination="zenoh")]})
    assert placed(config, 2) == [["z"], ["a"]]  # and the rest balanced around it


def test_the_config_says_how_many_workers() -> None:
    config = load_config(None)
    assert config.workers == 1
    assert BridgeConfig.model_validate({"workers": 4, "routes": [relay("a", "A")]}).workers == 4


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("workers: 0\nroutes: []\n", "bridge.yaml:1: workers: Input should be greater than or equal to 1"),
        ("routes:\n  - name: a\n    source: {transport: lcm, name: X}\n    translator: lcm_relay\n"
         "    destination: {transport: lcm, name: Y}\n    worker: -1\n",
         "bridge.yaml:6: routes.0.worker: Input should be greater than or equal to 0"),
    ],
)  # fmt: skip
def test_a_bad_count_or_pin_is_refused_at_load_with_its_line(tmp_path: Path, text: str, where: str) -> None:
    path = tmp_path / "bridge.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as refused:
        load_config(path)
    assert where in str(refused.value)


def test_groups_that_read_a_same_channel_share_a_worker() -> None:
    # "DRAW_(A|B)" reads DRAW_A, which "DRAW_.*" and "(?:LOAD|DRAW)_A" read too: one worker receives
    # and decodes it once; "OTHER" reads nothing of theirs and goes to the other worker.
    config = BridgeConfig.model_validate({"routes": [
        relay("scene", "(?:LOAD|DRAW)_A"), relay("draws", "DRAW_(A|B)"), relay("other", "OTHER"),
        relay("any_draw", "DRAW_.*"),
    ]})  # fmt: skip
    assert placed(config, 2) == [["scene", "draws", "any_draw"], ["other"]]


def test_a_group_that_reads_what_worker_0_must_read_joins_worker_0() -> None:
    # The Zenoh route must stay on worker 0; the LCM relay of its channel joins it there.
    config = BridgeConfig.model_validate({"routes": [
        relay("z", "DRAW", destination="zenoh"), relay("draws", "DRAW(_A)?"), relay("other", "OTHER"),
    ]})  # fmt: skip
    assert placed(config, 2) == [["z", "draws"], ["other"]]


def test_the_default_config_keeps_every_route_of_drakes_draws_on_one_worker() -> None:
    [first, *rest] = placed(load_config(None), 2)
    draws = {"tf", "link_markers", "markers", "poses", "foxglove_scene", "foxglove_transforms"}
    assert draws <= set(first)
    assert all(not draws & set(routes) for routes in rest)


def test_patterns_of_every_form_a_source_uses_are_placed_by_what_they_read() -> None:
    # Sets, classes, repeats, named groups, flags and lookaheads are sampled: "DRAW_[AB]\d{2}"
    # reads DRAW_A00, which "(?P<kind>DRAW|LOAD)_A\d+" reads too; "(?i)other" reads other, which
    # "(?!DRAW|LOAD).*" reads, and OTHER, which "OTHER(_X)?" reads. A backreference gives no sample
    # of its own: "(AB)\1" reads ABAB, which the lookahead's route reads too, an overlap missed
    # (it costs a second receive, never a message).
    config = BridgeConfig.model_validate({"routes": [
        relay("set", r"DRAW_[AB]\d{2}"), relay("named", r"(?P<kind>DRAW|LOAD)_A\d+"),
        relay("flagged", "(?i)other"), relay("rest", "(?!DRAW|LOAD).*"), relay("other", "OTHER(_X)?"),
        relay("twice", r"(AB)\1"),
    ]})  # fmt: skip
    assert placed(config, 3) == [["set", "named"], ["flagged", "rest", "other"], ["twice"]]
