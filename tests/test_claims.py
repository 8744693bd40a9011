"""tests/claims.py: the ROS 2 domain and LCM ports of a test process are its own while it lives."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.claims import LCM_BLOCK, claim, lcm_port
from tests.conftest import read_line

ROOT = Path(__file__).resolve().parent.parent
HOLDER = (
    "import sys; from pathlib import Path; from tests.claims import claim; "
    "print(claim('test', range(1000, 1003), 0, Path(sys.argv[1])), flush=True); sys.stdin.read()"
)


def holder(folder: Path) -> tuple[subprocess.Popen[str], int]:
    """A process holding the first free number of 1000..1002 (in `folder`), until its stdin closes."""
    process = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder)], cwd=ROOT, stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True)  # fmt: skip
    return process, int(read_line(process.stdout, "the number it claimed"))


def test_a_number_is_held_by_one_live_process_and_free_again_once_it_ends(tmp_path: Path) -> None:
    first, first_number = holder(tmp_path)
    second, second_number = holder(tmp_path)
    try:
        assert first_number != second_number
        assert first_number in (1000, 1001, 1002) and second_number in (1000, 1001, 1002)
    finally:
        assert first.stdin is not None
        first.stdin.close()
        first.wait(timeout=30)
    # The kernel dropped the ended process's lock: its number is claimed again (by this process).
    taken = [claim("test", range(1000, 1003), 0, tmp_path) for _ in range(2)]
    assert first_number in taken and second_number not in taken
    assert second.stdin is not None
    second.stdin.close()
    second.wait(timeout=30)


def test_this_processes_lcm_ports_are_one_block() -> None:
    ports = [lcm_port(offset) for offset in (0, 1, LCM_BLOCK - 1)]
    assert ports == [ports[0], ports[0] + 1, ports[0] + LCM_BLOCK - 1]
    assert ports[0] % LCM_BLOCK == 0
