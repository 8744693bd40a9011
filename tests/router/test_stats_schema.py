"""The shape of `--stats-json` (viewer_bridge/router/status.py `Snapshot`, docs/configuration.md):
the file says its schema version, and holds the keys the types name, no more and no fewer, whether
one process wrote it or the parent merged its workers' stats."""

from __future__ import annotations

import json
from pathlib import Path
from typing import get_type_hints

import pytest

from tests.cli.test_cli import demo_log, run
from viewer_bridge.config.bridge import load_config
from viewer_bridge.router.status import (
    STATS_SCHEMA,
    Percentiles,
    RouteSnapshot,
    Snapshot,
    TransportSnapshot,
)


def test_the_schema_is_version_1_with_its_keys_named() -> None:
    """A key added, dropped or renamed is a new schema: this test and the docs change with it."""
    assert STATS_SCHEMA == 1
    assert Snapshot.__required_keys__ == {"schema", "routes", "transports"}
    assert TransportSnapshot.__required_keys__ == {"errors"}
    assert Percentiles.__required_keys__ == {"p50", "p99", "max"}
    assert len(RouteSnapshot.__required_keys__) == 19 and not RouteSnapshot.__optional_keys__


@pytest.mark.parametrize("workers", [1, 2])
def test_the_stats_file_carries_its_schema_and_exactly_the_typed_keys(tmp_path: Path, workers: int) -> None:
    log = demo_log(tmp_path / "demo.lcmlog", 30)
    stats = tmp_path / "stats.json"
    result = run(
        "run", "-c", "builtin:foxglove", "--set", "foxglove.port=0", "--lcm-url", f"file://{log}?speed=0",
        "--stats-json", str(stats), "--workers", str(workers), "--duration", "60", "-q",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    document = json.loads(stats.read_text())
    assert document["schema"] == STATS_SCHEMA
    assert set(document) == Snapshot.__required_keys__
    routes = document["routes"]
    in_order = [route.name for route in load_config("builtin:foxglove").routes]
    assert list(routes) == in_order
    counts = {key for key, hint in get_type_hints(RouteSnapshot).items() if hint is int}
    for name, route in routes.items():
        assert set(route) == RouteSnapshot.__required_keys__, name
        assert all(type(route[key]) is int for key in counts), (name, route)
        for samples in (route["translate_ms"], route["latency_ms"]):
            assert set(samples) == Percentiles.__required_keys__, (name, samples)
    assert routes["foxglove_transforms"]["messages_in"] == 30  # every draw of the log, replayed
    assert all(set(entry) == TransportSnapshot.__required_keys__ for entry in document["transports"].values())
