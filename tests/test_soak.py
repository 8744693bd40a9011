"""A short run of bench/soak.py: the soak without errors or silent loss, and every fault recovered."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench" / "soak.py"


def soak_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_soak", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_a_short_soak_loses_nothing_silently(tmp_path: Path) -> None:
    result = soak_module().soak(tmp_path, minutes=0.1, rate_hz=500.0)
    assert result["errors"] == 0
    # Every draw sent was read by the bridge, or counted as dropped by the kernel: none vanished.
    assert result["received"] + result["dropped_by_kernel"] == result["sent"]
    assert result["delivered"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("fault", ["LCM publisher restarted", "bridge SIGKILLed, load_cache",
                                   "ROS subscriber restarted", "ign peer restarted",
                                   "Director viewer restarted", "render client left mid-upload"])  # fmt: skip
def test_the_bridge_recovers_from_each_fault_without_a_manual_step(fault: str, tmp_path: Path) -> None:
    assert soak_module().FAULTS[fault](tmp_path) is not None, f"{fault}: never recovered"
