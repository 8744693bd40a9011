"""Benches that cannot rot: `bench/all.py --smoke` runs every bench script at tiny sizes, and each
must still produce its rows (a script that fails or measures nothing fails this test by name)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "bench"


def bench_scripts() -> list[str]:
    """The scripts `bench/all.py` runs, as it finds them."""
    listed = subprocess.run([sys.executable, "-c", "import all; print(' '.join(all.scripts()))"], cwd=BENCH,
                            env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True,
                            check=True, timeout=120)  # fmt: skip
    return listed.stdout.split()


@pytest.mark.slow
def test_every_bench_script_produces_its_rows_at_smoke_size() -> None:
    scripts = bench_scripts()
    assert {"draw_codec", "router", "to_rerun", "translators"} <= set(scripts)  # the finder still finds them
    run = subprocess.run([sys.executable, "all.py", "--smoke"], cwd=BENCH, env={**os.environ, "PYTHONPATH": str(ROOT)},
                         capture_output=True, text=True, timeout=900)  # fmt: skip
    assert run.returncode == 0, run.stderr[-6000:]
    counts = dict(re.findall(r"^--- bench/(\w+)\.py: (\d+) rows in ", run.stderr, flags=re.MULTILINE))
    assert set(counts) == set(scripts), run.stderr[-6000:]
    table_rows = re.findall(r"^\| (\w+) \| ", run.stdout, flags=re.MULTILINE)
    for script in scripts:
        assert int(counts[script]) > 0
        assert table_rows.count(script) == int(counts[script]), (
            f"bench/{script}.py: its rows are not in the table"
        )
    assert "`bench/all.py --smoke`" in run.stdout
