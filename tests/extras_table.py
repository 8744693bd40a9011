"""Each extra alone, as a user installs it: the project's wheel, built once from this checkout, in
a fresh venv with the core and that ONE extra, running the extra's headline command.

    python -m tests.extras_table            # every extra; prints the table (markdown)
    python -m tests.extras_table foxglove   # the named extras only

tests/test_wheel.py runs the same rows as tests (one per extra) on the same wheel and core venv.

How it stays cheap: the wheel is built once; the core venv (`pip install WHEEL`) is made once and
never changed; each extra's venv is a copy of it by hard links (`cp -al`, a second), into which
pip then installs `WHEEL[extra]` (pip adds only the extra's distributions, from its cache). pip and
Python replace files rather than write into them, so the copies never change the core venv. A
copy's console scripts still name the core venv's interpreter: the commands run as
`python -m viewer_bridge`. No venv sees the checkout, this test's venv or its site-packages (no
`--system-site-packages`, no PYTHONPATH), and every command runs in a folder outside the checkout.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Extras that are other extras together or the test tools, not a part a user picks alone.
NOT_ALONE = {"all": "every extra together: tests/test_wheel.py runs the bridge's demo with it",
             "test": "the test tools: ./dev test installs them"}  # fmt: skip
# `[ros]` alone: the built-in config's routes whose ROS 2 types come as wheels. Its /tf and
# /tf_static need tf2_msgs, which PyPI has no wheel of: `[ros-build]` and `viewer-bridge
# ros-interfaces install` build it (the `ros-build` row), and without it `run` says so in one line.
ROS_ONLY = """\
routes:
  - name: poses
    source: {transport: lcm, name: "DRAKE_VIEWER_DRAW"}
    translator: drake_to_pose_array
    destination: {transport: ros, name: drake/poses}
  - name: shapes
    source: {transport: lcm, name: "DRAKE_VIEWER_LOAD_ROBOT"}
    translator: drake_to_shapes
    destination: {transport: ros, name: drake/shapes}
  - name: markers
    source: {transport: lcm, name: "DRAKE_VIEWER_(?:LOAD_ROBOT|DRAW)"}
    translator: drake_to_marker_array
    destination: {transport: ros, name: drake/markers}
"""


@dataclass(frozen=True)
class Step:
    """One command of a row: `viewer-bridge ARGS` (or `python ARGS` when `python`), run in the
    row's folder, which must exit `code` and print `expect` (a regex) on stdout or stderr."""

    args: tuple[str, ...]
    expect: str
    python: bool = False
    timeout: float = 600
    code: int = 0  # 2: a refusal the row shows on purpose

    def shown(self) -> str:
        words = ["<own LCM bus>" if word == "LCM" else word for word in self.args]
        shown = " ".join(("python" if self.python else "viewer-bridge", *words))
        return shown + (f" (exit {self.code})" if self.code else "")


@dataclass(frozen=True)
class Row:
    extra: str  # "" for the core alone
    steps: tuple[Step, ...]
    files: dict[str, str] = field(default_factory=dict)  # written into the row's folder first


def _run_demo(config: str, route: str, *more: str) -> Step:
    """`viewer-bridge run` on the demo scene, whose `route` must carry messages out."""
    return Step(("run", "-c", config, "--demo", "--duration", "6", "--lcm-url", "LCM", *more),
                rf" route {route}: in [1-9]\d* out [1-9]")  # fmt: skip


def _demo_alone(expect: str, code: int = 0) -> Step:
    """`viewer-bridge run --demo` with no -c: the built-in config's routes this one extra runs (or
    its own built-in config), after one line naming what was left out and the extra that adds it;
    with no extra of a transport, one line naming them (exit 2)."""
    return Step(("run", "--demo", "--duration", "3", "--lcm-url", "LCM"), expect, code=code)


NO_TRANSPORT = _demo_alone(
    r"^viewer-bridge run: no built-in config can run: this install has none of their extras", 2
)

# The core first: its demo log (`viewer-bridge demo`, as the README's tour records it) is what the
# rows after it read.
DEMO_LOG = Step(("demo", "--url", "file://demo.lcmlog?mode=w", "--duration", "1"), r"")
ROWS: dict[str, Row] = {
    row.extra: row
    for row in [
        Row("", (Step(("--version",), r"^viewer-bridge \d+\.\d+\.\d+$"), DEMO_LOG,
                 Step(("dump", "demo.lcmlog", "--channel", "DRAKE_VIEWER_LOAD_ROBOT"), r"DRAKE_VIEWER_LOAD_ROBOT"),
                 Step(("ros-interfaces", "generate", "-o", "src"),
                      r"^viewer-bridge ros-interfaces: Drake's other LCM types .* pip install 'viewer-bridge\[drake\]'$"))),
        Row("ros", (_run_demo("ros.yaml", "poses"),
                    # The built-in config: /tf needs tf2_msgs, built with [ros-build]; one line says so.
                    Step(("run", "--demo", "--duration", "1", "--lcm-url", "LCM"), code=2,
                         expect=r"^viewer-bridge run: the ROS 2 interface tf2_msgs/msg/TFMessage is not installed in "
                                r"this environment: viewer-bridge ros-interfaces install tf2_msgs\n\Z")),
            files={"ros.yaml": ROS_ONLY}),
        Row("foxglove", (DEMO_LOG, Step(("run", "-c", "builtin:foxglove", "--demo", "--duration", "6", "--lcm-url", "LCM",
                                         "--set", "foxglove.port=0"),
                                        r"Foxglove WebSocket server ws://127\.0\.0\.1:\d+(.|\n)*foxglove_scene in [1-9]"),
                         Step(("convert", "demo.lcmlog", "demo.mcap"), r"wrote demo\.mcap: \d+ messages"),
                         _demo_alone(r"the built-in config's 17 ROS 2 routes left out: they need rclpy, not installed: "
                                     r"pip install 'viewer-bridge\[ros\]'(.|\n)* 6 routes running \("))),
        Row("zenoh", (Step(("run", "-c", "builtin:zenoh", "--demo", "--duration", "6", "--lcm-url", "LCM"),
                           # translated; no router here
                           r"Zenoh client(.|\n)* route poses: in [1-9]\d* out [1-9]"),
                      _demo_alone(r"running -c builtin:zenoh, the built-in config of what is installed(.|\n)*"
                                  r"route poses: in [1-9]\d* out [1-9]"))),
        Row("ign", (_run_demo("builtin:ign", "pose_v", "--set", "ign.ip=127.0.0.1"),
                    _demo_alone(r"running -c builtin:ign, the built-in config of what is installed"))),
        Row("render", (DEMO_LOG, Step(("snapshot", "demo.lcmlog", "demo.png"), r"wrote demo\.png: \d+ links?"),
                       NO_TRANSPORT)),
        Row("rerun", (DEMO_LOG, Step(("convert", "demo.lcmlog", "demo.rrd"), r"wrote demo\.rrd: "),
                      _demo_alone(r"running -c builtin:rerun, the built-in config of what is installed"))),
        Row("ros-build", (Step(("ros-interfaces", "install", "--yes"), r"tf2_msgs", timeout=1500),
                          Step(("ros-interfaces", "status"), r"tf2_msgs: installed"))),
        Row("drake", (Step(("example", "shapes", "--duration", "1", "--lcm-url", "file://shapes.lcmlog?mode=w"), r""),
                      Step(("dump", "shapes.lcmlog", "--channel", "DRAKE_VIEWER_LOAD.*"), r"DRAKE_VIEWER_LOAD"),
                      NO_TRANSPORT)),
        Row("docs", (Step(("-m", "mkdocs", "--version"), r"mkdocs, version \d", python=True),)),
    ]
}  # fmt: skip


def extras() -> dict[str, list[str]]:
    """pyproject.toml's extras and their requirements."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    return dict(project["optional-dependencies"])


def normalized(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def requirement_names(requirements: Sequence[str]) -> list[str]:
    names = [
        normalized(re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0]) for requirement in requirements
    ]
    return [name for name in names if name != "viewer-bridge"]


def clean_env(**more: str) -> dict[str, str]:
    """This process's environment without what points at the checkout or its venv."""
    dropped = ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME", "VIEWER_BRIDGE_CORE_ONLY")
    return {**{k: v for k, v in os.environ.items() if k not in dropped}, **more}


def run(
    command: Sequence[str], cwd: Path, timeout: float = 900, **env: str
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        list(command),
        cwd=cwd,
        env=clean_env(**env),
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def _checked(result: subprocess.CompletedProcess[str], what: str) -> subprocess.CompletedProcess[str]:
    if result.returncode != 0:
        raise RuntimeError(
            f"{what} exited {result.returncode}:\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
        )
    return result


def build_wheel(out: Path) -> Path:
    """The project's wheel, built from this checkout into `out` (--no-isolation: hatchling is in
    the test extra, so nothing is downloaded to build it)."""
    out.mkdir(parents=True, exist_ok=True)
    _checked(run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(out), str(ROOT)], out),
             "python -m build")  # fmt: skip
    (path,) = out.glob("viewer_bridge-*.whl")
    return path


# No check for a newer pip on each install (a request to PyPI).
PIP_INSTALL = ("-m", "pip", "install", "--quiet", "--disable-pip-version-check")


def core_venv(root: Path, wheel: Path) -> Path:
    """A fresh venv with the wheel's core install (no extra); its folder."""
    venv = root / "core"
    _checked(run([sys.executable, "-m", "venv", str(venv)], root), "python -m venv")
    _checked(run([str(venv / "bin/python"), *PIP_INSTALL, str(wheel)], root), "pip install WHEEL")
    return venv


def clone(venv: Path, to: Path) -> Path:
    """A copy of `venv` at `to`, by hard links."""
    _checked(run(["cp", "-al", str(venv), str(to)], venv.parent), "cp -al")
    return to


def distributions(venv: Path) -> dict[str, str]:
    """The distributions installed in `venv`: normalized name -> version."""
    code = ("import importlib.metadata as m, json, re\n"
            "print(json.dumps({re.sub(r'[-_.]+', '-', d.metadata['Name']).lower(): d.version "
            "for d in m.distributions()}))")  # fmt: skip
    return dict(json.loads(_checked(run([str(venv / "bin/python"), "-c", code], venv), "listing").stdout))


@dataclass
class Outcome:
    extra: str
    added: dict[str, str]  # what pip added to the core venv: name -> version
    direct: list[str]  # the extra's own requirements
    step: Step | None  # the command that failed, or None
    code: int
    seconds: float  # the install and the commands
    output: str  # the failed step's, or the last step's

    @property
    def ok(self) -> bool:
        return self.step is None and self.code == 0

    def installed(self) -> str:
        top = [f"{name} {self.added[name]}" for name in self.direct if name in self.added]
        rest = len(self.added) - len(top)
        return ", ".join(top) + (f" (+{rest} more)" if rest else "") if self.added else "nothing (the core)"


def try_extra(row: Row, wheel: Path, core: Path, work: Path, lcm: str) -> Outcome:
    """Install the core and `row.extra` alone (a copy of `core`), then run the row's commands."""
    folder = work / (row.extra or "core")
    folder.mkdir(parents=True)
    venv = clone(core, folder / "venv") if row.extra else core
    started = time.monotonic()
    before = distributions(venv)
    if row.extra:
        pip = [str(venv / "bin/python"), *PIP_INSTALL, f"{wheel}[{row.extra}]"]
        installed = run(pip, folder, timeout=1500)
        if installed.returncode != 0:
            return Outcome(row.extra, {}, [], Step(("pip", "install", f"WHEEL[{row.extra}]"), ""),
                           installed.returncode, time.monotonic() - started, installed.stderr[-3000:])  # fmt: skip
    after = distributions(venv)
    added = {name: version for name, version in sorted(after.items()) if before.get(name) != version}
    direct = requirement_names(extras().get(row.extra, []))
    for name, text in row.files.items():
        (folder / name).write_text(text)
    output = ""
    for step in row.steps:
        args = [lcm if word == "LCM" else word for word in step.args]
        command = [str(venv / "bin/python"), *(args if step.python else ["-m", "viewer_bridge", *args])]
        result = run(command, folder, timeout=step.timeout, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        output = result.stdout + result.stderr
        failed = (result.returncode != step.code or "Traceback" in output
                  or not re.search(step.expect, output, re.MULTILINE))  # fmt: skip
        if failed:
            return Outcome(
                row.extra, added, direct, step, result.returncode, time.monotonic() - started, output
            )
    return Outcome(row.extra, added, direct, None, 0, time.monotonic() - started, output)


def table(outcomes: Sequence[Outcome]) -> str:
    lines = [
        "| extra | what pip added to the core | command | exit code | seconds |",
        "|---|---|---|---|---|",
    ]
    for outcome in outcomes:
        row = ROWS[outcome.extra]
        # the rows' shared setup
        steps = [step for step in row.steps if step is not DEMO_LOG or not row.extra]
        shown = outcome.step.shown() if outcome.step else "`; `".join(step.shown() for step in steps)
        status = str(outcome.code) + ("" if outcome.ok else " (FAILED)")
        extra = f"`[{outcome.extra}]`" if outcome.extra else "core"
        lines.append(f"| {extra} | {outcome.installed()} | `{shown}` | {status} | {outcome.seconds:.0f} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tests.extras_table", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument(
        "extras", nargs="*", help="the extras to try, `core` for none (default: the core and every extra)"
    )
    parser.add_argument("--work", type=Path, help="the folder to build in (default: a new temporary one)")
    args = parser.parse_args(argv)
    import tempfile

    work = args.work or Path(tempfile.mkdtemp(prefix="extras-table-"))
    chosen = [("" if name == "core" else name) for name in args.extras] or list(ROWS)
    print(f"building the wheel and the core venv in {work} ...", file=sys.stderr)
    wheel = build_wheel(work / "dist")
    core = core_venv(work, wheel)
    outcomes = []
    for offset, extra in enumerate(chosen):
        started = time.monotonic()
        outcome = try_extra(
            ROWS[extra], wheel, core, work / "rows", f"udpm://239.255.76.67:{7300 + offset}?ttl=0"
        )
        print(f"[{extra or 'core'}] {'ok' if outcome.ok else 'FAILED'} in {time.monotonic() - started:.0f} s",
              file=sys.stderr)  # fmt: skip
        if not outcome.ok:
            print(outcome.output[-3000:], file=sys.stderr)
        outcomes.append(outcome)
    print(table(outcomes))
    return 0 if all(outcome.ok for outcome in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
