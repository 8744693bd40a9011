"""Coverage-guided fuzzing with atheris (libFuzzer) of every decoder and parser the bridge exposes.

Run: .venv/bin/python bench/fuzz.py [--runs 1000000] [--only TARGET ...] [--list]

Each target (tests/fuzz/targets.py: the LCM codecs of every schema, Drake's load and draw
decoders, the tree viewer's request path, the ign protobuf paths, ign discovery datagrams, the
glTF reader, the render server's form parser, contact results and point clouds both ways, the
config loader, rmw_zenoh's data keys, liveliness tokens and attachments, what a Foxglove client
sends through the front (its byte stream and its framed messages), what the SDK sends back
through the front's relay, a request's head and origin at the front's door, and the
allowed-origin matcher) runs under libFuzzer in a process of its own
(a fork of one process that instrumented the bridge's modules for coverage once), for `--runs`
executions. Its corpus is kept in `.fuzz-corpus/<target>/` across runs and seeded from a real
Drake capture (tests/fuzz/seeds.py). A finding is an exception outside the target's documented
error types, a crash, an input slower than `--timeout` seconds (a hang) or the process passing
`--rss-mb` (memory growth); its input is saved as `.fuzz-corpus/<target>-crash-*`.
The report: per target, executions, executions per second, coverage (libFuzzer's `cov`
edges and `ft` features) at the end, new coverage in the last 10% of the run, peak RSS, findings.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

TOP = Path(__file__).resolve().parent.parent
CORPUS = TOP / ".fuzz-corpus"
# "#123456	NEW    cov: 1200 ft: 3400 corp: 80/2Kb lim: 4 exec/s: 20000 rss: 150Mb"
_PROGRESS = re.compile(r"^#(\d+)\s+(\w+)\s+cov: (\d+) ft: (\d+).*?rss: (\d+)Mb")
_STAT = re.compile(r"^stat::(\w+):\s+(\d+)")


@dataclass
class Report:
    target: str
    executions: int = 0
    exec_per_s: float = 0.0
    cov: int = 0
    ft: int = 0
    cov_last_10: int = 0  # edges first covered in the last 10% of the executions
    ft_last_10: int = 0
    peak_rss_mb: int = 0
    finding: str = ""
    seconds: float = 0.0


def zygote(names: list[str], runs: int, timeout: int, rss_mb: int, seeds: Path, logs: Path) -> None:
    """In the one fuzzing process: instrument the bridge once, then fuzz each target in a fork.

    Instrumenting and importing the bridge is most of a short run's cost (a few seconds of CPU,
    the 2000 executions a fraction of one): paid once here, every target's fork inherits it. A
    fork's libFuzzer output goes to `logs/<target>.log`; a line `<target> <exit status>` on
    stdout says it ended."""
    import atheris

    with atheris.instrument_imports(include=["viewer_bridge"]):
        from tests.fuzz.targets import TARGETS
    for name in names:
        pid = os.fork()
        if pid == 0:
            _fuzz_in_fork(TARGETS[name], name, runs, timeout, rss_mb, seeds / name, logs / f"{name}.log")
        _, status = os.waitpid(pid, 0)
        print(name, os.waitstatus_to_exitcode(status), flush=True)


def _fuzz_in_fork(
    target: Any, name: str, runs: int, timeout: int, rss_mb: int, seeds: Path, log: Path
) -> None:
    """Hand `target` to libFuzzer (which ends this process), its output to `log`."""
    import atheris

    with log.open("wb") as output:
        os.dup2(output.fileno(), 1)
        os.dup2(output.fileno(), 2)

    def one_input(data: bytes) -> None:
        with contextlib.suppress(target.documented):  # a documented refusal: what the target promises
            target.run(data)

    corpus = CORPUS / name
    crash_prefix = f"{CORPUS}/{name}-"
    try:
        atheris.Setup([sys.argv[0], f"-runs={runs}", f"-timeout={timeout}", f"-rss_limit_mb={rss_mb}",
                       "-print_final_stats=1", f"-artifact_prefix={crash_prefix}", str(corpus), str(seeds)],
                      one_input)  # fmt: skip
        atheris.Fuzz()
    finally:
        os._exit(70)  # libFuzzer exits the process itself; returning here is a failure of the fork


def run_targets(names: list[str], runs: int, timeout: int, rss_mb: int, seeds: Path) -> Iterator[Report]:
    """Each target's report, as its run ends (every target in one fuzzing process: `zygote`)."""
    with tempfile.TemporaryDirectory() as scratch:
        per_target, logs = Path(scratch) / "seeds", Path(scratch) / "logs"
        logs.mkdir()
        for name in names:  # the target's seed kinds, flattened into one directory
            (CORPUS / name).mkdir(parents=True, exist_ok=True)
            (per_target / name).mkdir(parents=True)
            for kind in _seed_kinds(name):
                for path in (seeds / kind).glob("*") if (seeds / kind).is_dir() else ():
                    (per_target / name / path.name).write_bytes(path.read_bytes())
        command = [sys.executable, __file__, "--zygote", "--runs", str(runs), "--timeout", str(timeout),
                   "--rss-mb", str(rss_mb), "--seeds", str(per_target), "--logs", str(logs), *names]  # fmt: skip
        started = time.monotonic()
        with subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=TOP,
                              env=dict(os.environ, PYTHONPATH=str(TOP))) as process:  # fmt: skip
            assert process.stdout is not None and process.stderr is not None
            for line in process.stdout:
                name, status = line.split()
                yield _report(
                    name, (logs / f"{name}.log").read_text(errors="replace"), runs, int(status), started
                )
                started = time.monotonic()
            problem = process.stderr.read()
        if process.returncode != 0:  # instrumenting or importing failed: no target ran
            raise SystemExit(
                f"the fuzzing process failed (exit status {process.returncode}): {_last_lines(problem, 10)}"
            )


def _report(name: str, output: str, runs: int, status: int, started: float) -> Report:
    report = parse(name, output, runs)
    report.seconds = time.monotonic() - started
    if not report.exec_per_s:  # libFuzzer's average is 0 for a run under a second
        report.exec_per_s = report.executions / report.seconds
    if status != 0 and not report.finding:
        report.finding = f"exit status {status}: " + _last_lines(output)
    return report


def _seed_kinds(name: str) -> tuple[str, ...]:
    from tests.fuzz.targets import TARGETS

    return TARGETS[name].seed_kinds


def parse(name: str, output: str, runs: int) -> Report:
    """libFuzzer's progress lines and final stats -> a report."""
    report = Report(name)
    progress: list[tuple[int, int, int, int]] = []  # executions, cov, ft, rss
    for line in output.splitlines():
        if match := _PROGRESS.match(line):
            executions, _, cov, ft, rss = match.groups()
            progress.append((int(executions), int(cov), int(ft), int(rss)))
        elif match := _STAT.match(line):
            key, value = match.groups()
            if key == "number_of_executed_units":
                report.executions = int(value)
            elif key == "average_exec_per_sec":
                report.exec_per_s = float(value)
            elif key == "peak_rss_mb":
                report.peak_rss_mb = int(value)
        elif "==ERROR" in line or "Uncaught Python exception" in line or "ERROR: libFuzzer" in line:
            report.finding = report.finding or line.strip()
    if progress:
        report.cov, report.ft = progress[-1][1], progress[-1][2]
        mark = 0.9 * max(report.executions, runs if not report.finding else progress[-1][0])
        before = [entry for entry in progress if entry[0] <= mark] or progress[:1]
        report.cov_last_10 = report.cov - before[-1][1]
        report.ft_last_10 = report.ft - before[-1][2]
    if report.finding:
        report.finding += " | " + _last_lines(output, 6)
    return report


def _last_lines(text: str, count: int = 3) -> str:
    return " / ".join(line.strip() for line in text.strip().splitlines()[-count:])


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=1_000_000, help="executions per target")
    parser.add_argument("--only", nargs="*", help="these targets only")
    parser.add_argument("--timeout", type=int, default=10, help="seconds one input may take (a hang)")
    parser.add_argument("--rss-mb", type=int, default=2048, help="memory limit of a fuzzing process")
    parser.add_argument("--list", action="store_true", help="list the targets")
    parser.add_argument("--zygote", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--seeds", help=argparse.SUPPRESS)
    parser.add_argument("--logs", help=argparse.SUPPRESS)
    parser.add_argument("names", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.zygote:
        return zygote(args.names, args.runs, args.timeout, args.rss_mb, Path(args.seeds), Path(args.logs))
    from tests.fuzz.seeds import write_seeds
    from tests.fuzz.targets import TARGETS

    if args.list:
        print("\n".join(TARGETS))
        return None
    names = [name for name in TARGETS if not args.only or name in args.only]
    print(f"{'target':<52} {'executions':>10} {'exec/s':>7} {'cov':>6} {'ft':>6} {'new cov/ft, last 10%':>20} "
          f"{'peak RSS':>8}  findings")  # fmt: skip
    findings = 0
    with tempfile.TemporaryDirectory() as seeds:
        write_seeds(Path(seeds))
        for r in run_targets(names, args.runs, args.timeout, args.rss_mb, Path(seeds)):
            name = r.target
            findings += bool(r.finding)
            print(f"{name:<52} {r.executions:>10} {r.exec_per_s:>7.0f} {r.cov:>6} {r.ft:>6} "
                  f"{f'{r.cov_last_10} / {r.ft_last_10}':>20} {r.peak_rss_mb:>6}MB  {r.finding or 'none'}",
                  flush=True)  # fmt: skip
    if findings:
        raise SystemExit(f"{findings} target(s) with findings; inputs in {CORPUS}")
    return None


if __name__ == "__main__":
    main()
