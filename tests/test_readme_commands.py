"""The README's command list, run top to bottom as a user would run it.

The commands come from README.md itself: every line of the fenced bash blocks of the sections
named in SECTIONS (a `\\` continuation joined to its next line, the trailing comment removed,
comment-only lines skipped). Each runs through bash in one temporary folder holding `drake.lcmlog`
(lcm-logger's recording of a pydrake simulation with contacts, tests/drake_contact_scene.py: the
default unsuffixed channels and CONTACT_RESULTS) and an empty `mappings/`, with the venv's
`viewer-bridge` first on PATH. What the test changes in them, and why, is all in SUBSTITUTIONS (applied in order to every
command) and RUN_DEFAULTS; every other character is the README's. A command must exit as the
README says: 0, unless its own comment names another code (`# ... exit 2`), and no command may
print a traceback.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import lcm_url, record_log

pytestmark = pytest.mark.slow
README = Path(__file__).parents[1] / "README.md"
CONTACT_SCENE = Path(__file__).parent / "drake_contact_scene.py"
SECTIONS = ("Command line",)  # the `## ` headings whose bash blocks are run
LCM = lcm_url(31)  # this test's own LCM port: the README's default one is shared by the machine

# (what the README says, as a regex; what runs instead, `{lcm}` for LCM above, a newline between
# several commands; why).
SUBSTITUTIONS: list[tuple[str, str, str]] = [
    (r"^viewer-bridge dump --live$", "viewer-bridge dump --live '{lcm}' --duration 1",
     "the README's listens on the shared default bus until Ctrl-C"),
    (r"udpm://239\.255\.76\.67:7668\?ttl=0", "{lcm}", "this test's own bus"),
    (r"--duration 5$", "--duration 1", "shorter"),
    (r"\[--url URL\] \[--rate 60\] \[--duration S\]", "--url '{lcm}' --rate 60 --duration 1",
     "the optional arguments, given"),
    (r"\[-c CONFIG\] \[--stats-json PATH\] \[--stats-period 5\] \[--duration S\] \[--demo\]",
     "-c builtin:default --stats-json stats.json --stats-period 1 --duration 2 --demo",
     "the optional arguments, given"),
    (r"foxglove\.port=9000", "foxglove.port=0", "any free port: other bridges may be running here"),
    (r"^(viewer-bridge convert \S+) out\.mcap \[--schema ros2\|foxglove\]$",
     "\\1 out-ros2.mcap --schema ros2\n\\1 out-foxglove.mcap --schema foxglove",
     "each schema, each into a file of its own"),
    (r"\[-c CONFIG\]", "-c builtin:default", "the optional argument, given"),
    (r"^(viewer-bridge ros-interfaces) install\|status$", "\\1 install\n\\1 status", "each action"),
]  # fmt: skip

# What every `viewer-bridge run` gets unless it already names it (a run would go on until Ctrl-C,
# listen on the shared default bus and take the Foxglove port 8765), inserted right after `run`
# so that `--ros-args ...` stays last: (what shows it is named, the option).
RUN_DEFAULTS = [
    ("--duration", "--duration 2"),
    ("--lcm-url", "--lcm-url '{lcm}'"),
    ("foxglove.port=", "--set foxglove.port=0"),
]


def readme_commands(text: str) -> list[str]:
    """The command lines of the bash blocks in SECTIONS, top to bottom."""
    commands: list[str] = []
    for section in re.split(r"^## ", text, flags=re.MULTILINE):
        if section.split("\n", 1)[0].strip() not in SECTIONS:
            continue
        for block in re.findall(r"^```bash\n(.*?)^```", section, flags=re.MULTILINE | re.DOTALL):
            for line in block.replace("\\\n", " ").splitlines():
                if line.strip() and not line.lstrip().startswith("#"):
                    commands.append(line.strip())
    return commands


def without_comment(line: str) -> tuple[str, str]:
    """A bash line split into its command and its trailing comment (a `#` outside quotes)."""
    quote = ""
    for index, character in enumerate(line):
        if quote:
            quote = "" if character == quote else quote
        elif character in "'\"":
            quote = character
        elif character == "#" and (index == 0 or line[index - 1].isspace()):
            return line[:index].rstrip(), line[index + 1 :].strip()
    return line, ""


def adapted(command: str) -> list[str]:
    """What runs for one README command: SUBSTITUTIONS, then RUN_DEFAULTS."""
    for pattern, replacement, _why in SUBSTITUTIONS:
        command = re.sub(pattern, replacement, command)
    result = []
    for each in command.split("\n"):
        if each.startswith("viewer-bridge run"):
            missing = [option for marker, option in RUN_DEFAULTS if marker not in each]
            each = " ".join(["viewer-bridge run", *missing, each.removeprefix("viewer-bridge run").strip()]).strip()
        result.append(each.format(lcm=LCM))
    return result


def expected_exit(comment: str) -> int:
    found = re.search(r"\bexit (\d+)", comment)
    return int(found.group(1)) if found else 0


CASES = [
    pytest.param(run, expected_exit(comment), id=run)
    for line in readme_commands(README.read_text())
    for command, comment in [without_comment(line)]
    for run in adapted(command)
]


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("readme")
    url = lcm_url(32)
    record_log(folder / "drake.lcmlog", url, [sys.executable, str(CONTACT_SCENE), url, "0.5"])
    (folder / "mappings").mkdir()
    return folder


def test_the_readme_lists_commands() -> None:
    assert len(CASES) >= 15, [case.values for case in CASES]  # a README whose list was not found


@pytest.mark.parametrize(("command", "exit_code"), CASES)
def test_a_readme_command_exits_as_the_readme_says(command: str, exit_code: int, folder: Path) -> None:
    path = f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"  # the venv's viewer-bridge
    result = subprocess.run(
        ["bash", "-c", command], cwd=folder, capture_output=True, text=True, timeout=180,
        env={**os.environ, "PATH": path, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    assert result.returncode == exit_code, result.stderr[-3000:]
    assert "Traceback" not in result.stderr, result.stderr[-3000:]
