"""How many workers `--workers auto` runs, and when workers are said to compete for cores
(`viewer_bridge.router.cores`), from given figures: no machine's load decides these tests."""

from __future__ import annotations

import os
import pickle
import time

import pytest

from tests.router.test_placement import relay
from viewer_bridge.config.bridge import BridgeConfig, load_config
from viewer_bridge.router.cores import CoreSample, CoreWatch, competing
from viewer_bridge.router.workers import Started, Stats, auto_workers, useful_workers

FOUR_SOURCES = BridgeConfig.model_validate({"routes": [relay(name, name.upper()) for name in "abcd"]})


@pytest.mark.parametrize(
    ("cores", "busy", "expected"),
    [
        (1, 0.0, 1),  # one core: one process
        (2, 0.0, 1),  # two idle cores: one for the bridge, one for the peers
        (2, 1.9, 1),  # a busy machine: never fewer than 1
        (4, 0.0, 3),
        (4, 1.0, 2),  # a core's worth of other work leaves 3 free, one kept for the peers
        (4, 0.8, 2),  # 3.2 free: 3, less the peers' one
        (64, 0.0, 4),  # more cores than the routes can use: a worker per source
    ],
)
def test_auto_counts_the_free_cores_less_one_for_the_peers_up_to_what_the_routes_use(
    cores: int, busy: float, expected: int
) -> None:
    chosen = auto_workers(FOUR_SOURCES, cores=cores, busy=busy)
    assert chosen.workers == expected
    assert f"--workers auto: {expected} ({cores} usable cores" in chosen.why()


def test_auto_runs_enough_workers_for_every_pinned_route() -> None:
    config = BridgeConfig.model_validate({"routes": [relay("a", "A"), relay("b", "B", worker=2)]})
    assert auto_workers(config, cores=2, busy=0.0).workers == 3


def test_routes_that_read_the_same_channels_count_as_one_for_auto() -> None:
    config = BridgeConfig.model_validate(
        {"routes": [relay("a1", "A"), relay("a2", "A(_X)?"), relay("b", "B")]}
    )
    assert useful_workers(config) == 2
    assert (
        auto_workers(load_config(None), cores=256, busy=0.0).workers == useful_workers(load_config(None)) > 1
    )


def test_auto_watches_this_machine_when_given_nothing() -> None:
    chosen = auto_workers(FOUR_SOURCES)
    assert chosen.cores == len(os.sched_getaffinity(0)) and chosen.busy >= 0.0
    assert 1 <= chosen.workers <= 4


def sample(ran: float, waited: float, seconds: float = 5.0, stolen: float = 0.0) -> CoreSample:
    return CoreSample(
        seconds=seconds, workers=2, cores=2, ran=ran, waited=waited, machine_busy=9.9, stolen=stolen
    )


def test_workers_that_wait_for_a_core_a_quarter_of_the_time_they_run_compete() -> None:
    said = competing(sample(ran=6.0, waited=3.0))
    assert said is not None
    assert said.startswith(
        "the 2 workers compete for cores: they waited 0.50 s for a core per second they ran"
    )
    assert "the machine used 1.98 of its 2 cores" in said and "--workers auto" in said
    assert "stolen by the hypervisor" in (competing(sample(ran=6.0, waited=3.0, stolen=1.0)) or "")


@pytest.mark.parametrize(
    ("ran", "waited"),
    [(6.0, 1.0), (0.2, 0.2), (0.0, 0.0)],  # short waits; idle workers (their waits say nothing)
)
def test_workers_that_get_their_cores_or_idle_do_not_compete(ran: float, waited: float) -> None:
    assert competing(sample(ran=ran, waited=waited)) is None


def test_the_watch_reads_this_process_and_starts_anew_when_the_workers_change() -> None:
    watch = CoreWatch()
    assert watch.sample([os.getpid()]) is None  # the first look has nothing to compare with
    # The kernel adds a running thread's time at its ticks: work until a look has seen some.
    deadline = time.monotonic() + 30.0
    while True:
        until = time.monotonic() + 0.05
        while time.monotonic() < until:
            pass
        later = watch.sample([os.getpid()])
        if later is None or later.ran > 0.0 or time.monotonic() > deadline:
            break
    assert later is not None and later.ran > 0.0 and later.workers == 1 and later.seconds > 0.0
    assert watch.sample([os.getpid(), os.getppid()]) is None


def test_worker_messages_are_small_typed_records() -> None:
    started, snapshot = Started(pid=1234), Stats({"poses": {"messages_in": 1}})
    assert pickle.loads(pickle.dumps(started)) == started and isinstance(
        pickle.loads(pickle.dumps(started)), Started
    )
    assert pickle.loads(pickle.dumps(snapshot)).stats == {"poses": {"messages_in": 1}}
    assert len(pickle.dumps(started, pickle.HIGHEST_PROTOCOL)) < 80
