"""The end-to-end test files, run again and again while both cores are kept busy: the races a quiet
machine hides show up as failures here.

Run: .venv/bin/python -m tests.stress N [--jobs J] [pytest args]   (`./dev test --stress N ...`)

The files are those marked `e2e` (they start peers or bridges; see pyproject.toml's markers).
Each round runs every file once, in a pytest process of its own, so a failure in one run cannot
leak into the next; `--jobs J` runs J files at once (as `./dev test` runs two test processes
side by side). Two `nice -n 19` busy loops take whatever CPU the tests leave, and are ended
however the run ends. At the end, a table: file, runs, failures, slowest run; each failed run's
output is kept in a log file the table names.
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType

from tests.process_groups import end_groups

ROOT = Path(__file__).resolve().parent.parent
MARKER = "e2e"
BUSY_LOOPS = 2  # one per core of the machine the suite is held to
# A file's run that outlives every test's own deadline (pytest-timeout's, in pyproject.toml) is
# stuck outside any test (collection, a session fixture's teardown): ended, and counted failed.
FILE_DEADLINE_S = 3 * 3600


@dataclass
class FileRuns:
    runs: int = 0
    failures: int = 0
    slowest_s: float = 0.0
    failed_logs: list[Path] = field(default_factory=list)


def e2e_files(pytest_args: list[str]) -> list[str]:
    """The test files with at least one test marked e2e (and chosen by `pytest_args`), in suite order."""
    listed = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", "-m", MARKER, *pytest_args],
        cwd=ROOT, capture_output=True, text=True, check=False,
    )  # fmt: skip
    if listed.returncode not in (0, 5):  # 5: none collected, reported below
        raise SystemExit(
            f"collecting the {MARKER} tests failed:\n{listed.stdout[-3000:]}{listed.stderr[-3000:]}"
        )
    files = dict.fromkeys(line.split("::")[0] for line in listed.stdout.splitlines() if "::" in line)
    if not files:
        raise SystemExit(f"no test marked {MARKER} among {' '.join(pytest_args) or 'the suite'}")
    return list(files)


@contextmanager
def busy_cores(count: int = BUSY_LOOPS) -> Iterator[None]:
    """`count` lowest-priority busy loops for the length of the block, ended whatever happens."""
    loops = [subprocess.Popen(["nice", "-n", "19", sys.executable, "-c", "while True: pass"], start_new_session=True)
             for _ in range(count)]  # fmt: skip
    try:
        yield
    finally:
        end_groups(loops, grace=5)


def run_file(path: str, pytest_args: list[str], logs: Path, round_number: int) -> tuple[bool, float, Path]:
    """One pytest run of `path`: whether it passed, its seconds, and the file its output went to."""
    log = logs / f"{path.replace('/', '_')}.{round_number}.log"
    started = time.monotonic()
    with log.open("w") as out:
        process = subprocess.Popen(
            [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", MARKER, path, *pytest_args],
            cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
        try:
            returncode = process.wait(timeout=FILE_DEADLINE_S)
        except subprocess.TimeoutExpired:
            returncode = -1
        finally:
            end_groups([process], grace=10)  # what the run left behind, if anything
    return returncode == 0, time.monotonic() - started, log


def table(results: dict[str, FileRuns]) -> str:
    width = max(len("file"), *(len(path) for path in results))
    lines = [f"{'file':<{width}}  runs  failures  slowest (s)", f"{'-' * width}  ----  --------  -----------"]
    for path, runs in results.items():
        lines.append(f"{path:<{width}}  {runs.runs:>4}  {runs.failures:>8}  {runs.slowest_s:>11.1f}")
    return "\n".join(lines)


def _raise_on_termination(signum: int, frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)  # so that the busy loops' `finally` ends them


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("rounds", type=int, help="how many times each file runs")
    parser.add_argument("--jobs", type=int, default=1,
                        help="files run at once (each a test process of its own, as `./dev test`'s workers)")  # fmt: skip
    parser.add_argument(
        "pytest_args", nargs=argparse.REMAINDER, help="passed to every pytest run (e.g. a file)"
    )
    args = parser.parse_args()
    if "--jobs" in args.pytest_args:  # after N too (argparse's remainder takes everything after N)
        at = args.pytest_args.index("--jobs")
        args.jobs = int(args.pytest_args[at + 1])
        del args.pytest_args[at : at + 2]
    signal.signal(signal.SIGTERM, _raise_on_termination)
    files = e2e_files(args.pytest_args)
    # Each file is run on its own; the other arguments (options, and their values) go to every run.
    options = [arg for arg in args.pytest_args if not (ROOT / arg.split("::")[0]).exists()]
    results = {path: FileRuns() for path in files}
    logs = Path(tempfile.mkdtemp(prefix="viewer-bridge-stress-"))
    print(f"{len(files)} files x {args.rounds} rounds, {args.jobs} at once, {BUSY_LOOPS} busy loops; logs in {logs}",
          flush=True)  # fmt: skip
    with busy_cores(), ThreadPoolExecutor(args.jobs) as pool:
        for round_number in range(1, args.rounds + 1):
            runs_of_round = {path: pool.submit(run_file, path, options, logs, round_number) for path in files}
            for path, run in runs_of_round.items():
                passed, seconds, log = run.result()
                runs = results[path]
                runs.runs += 1
                runs.slowest_s = max(runs.slowest_s, seconds)
                if passed:
                    log.unlink()
                else:
                    runs.failures += 1
                    runs.failed_logs.append(log)
                print(f"round {round_number}: {path} {'passed' if passed else 'FAILED'} in {seconds:.1f} s",
                      flush=True)  # fmt: skip
    print(table(results))
    for path, runs in results.items():
        for log in runs.failed_logs:
            print(f"failed: {path}: {log}")
    if not any(logs.iterdir()):
        logs.rmdir()  # every run passed: nothing to read
    return 1 if any(runs.failures for runs in results.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
