"""The README's command list, run top to bottom as a user would run it.

The commands come from README.md itself: every line of the fenced bash blocks of the sections
named in SECTIONS (a `\\` continuation joined to its next line, the trailing comment removed,
comment-only lines skipped). Each runs through bash in one temporary folder holding `drake.lcmlog`
and an empty `mappings/`, with the venv's `viewer-bridge` first on PATH. The log is lcm-logger's
recording of two pydrake simulations, one after the other: viewer_bridge/examples/contacts.py (Drake's
default unsuffixed channels and CONTACT_RESULTS) and viewer_bridge/examples/shapes.py (role-suffixed
channels, `--role illustration`).

What the test changes in the commands, and why, is all in SUBSTITUTIONS (applied in order to
every command), RUN_DEFAULTS and SERVERS; every other character is the README's. A command must
exit as the README says: 0, unless its own comment names another code (`# ... exit 2`); a server
must say it is ready and then stop on Ctrl-C (SIGINT) with 0. No command may print a traceback.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import pytest

from tests.conftest import EXAMPLES, lcm_url, record_log

pytestmark = pytest.mark.slow
README = Path(__file__).parents[1] / "README.md"
CONTACT_SCENE = EXAMPLES / "contacts.py"
SCENE = EXAMPLES / "shapes.py"
SECTIONS = ("Command line", "glTF: export, snapshots, and a render server for Drake's cameras")  # `## ` headings
LCM = lcm_url(31)  # this test's own LCM port: the README's default one is shared by the machine


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


PORT = _free_port()  # for servers the README runs on a fixed port

# (what the README says, as a regex; what runs instead, `{lcm}` for LCM above, a newline between
# several commands; why).
SUBSTITUTIONS: list[tuple[str, str, str]] = [
    (r"^viewer-bridge dump --live$", "viewer-bridge dump --live '{lcm}' --duration 1",
     "the README's listens on the shared default bus until Ctrl-C"),
    (r"udpm://239\.255\.76\.67:7668\?ttl=0", "{lcm}", "this test's own bus"),
    (r"--duration 5$", "--duration 1", "shorter"),
    (r"\[--url URL\] \[--rate 60\] \[--duration S\]", "--url '{lcm}' --rate 60 --duration 1",
     "the optional arguments, given"),
    (r"\[-c CONFIG\] \[--stats-json PATH\] \[--stats-period 5\] \[--duration S\] \[--demo\] \[--quiet\]",
     "-c builtin:default --stats-json stats.json --stats-period 1 --duration 2 --demo --quiet",
     "the optional arguments, given"),
    (r"foxglove\.port=9000", "foxglove.port=0", "any free port: other bridges may be running here"),
    (r"^(viewer-bridge convert \S+) out\.mcap \[--schema ros2\|foxglove\] \[--force\]$",
     "\\1 out-ros2.mcap --schema ros2\n\\1 out-foxglove.mcap --schema foxglove\n"
     "\\1 out-foxglove.mcap --schema foxglove --force",
     "each schema, each into a file of its own; then --force over an existing one"),
    (r"\[-c CONFIG\]", "-c builtin:default", "the optional argument, given"),
    (r"^(viewer-bridge ros-interfaces) install\|status$", "\\1 install\n\\1 status", "each action"),
    (r"\[--host 127\.0\.0\.1\] \[--port 8000\] \[--max-upload BYTES\]",
     "--host 127.0.0.1 --port {port} --max-upload 1000000", "the optional arguments, given; a free port"),
    (r"\[--size 640x480\] \[--fov 45\] \[--camera EX,EY,EZ,TX,TY,TZ\]",
     "--size 640x480 --fov 45 --camera 2,2,1.5,0,0,0", "the optional arguments, given"),
    (r"^(viewer-bridge snapshot \S+) out\.png (.*)\[--image color\|label\|depth\](.*)$",
     "\\1 color.png \\2--image color\\3\n\\1 label.png \\2--image label\\3\n\\1 depth.png \\2--image depth\\3",
     "each image, each into a file of its own"),
]  # fmt: skip

# What every `viewer-bridge run` gets unless it already names it (a run would go on until Ctrl-C,
# listen on the shared default bus and take the Foxglove port 8765), inserted right after `run`
# so that `--ros-args ...` stays last: (what shows it is named, the option).
RUN_DEFAULTS = [
    ("--duration", "--duration 2"),
    ("--lcm-url", "--lcm-url '{lcm}'"),
    ("foxglove.port=", "--set foxglove.port=0"),
]

# Commands that serve until Ctrl-C, by how they start: the line each logs once it is ready.
SERVERS = {"viewer-bridge serve-render": "render server on"}


def readme_commands(text: str) -> list[str]:
    """The command lines of the bash blocks in SECTIONS, top to bottom."""
    commands: list[str] = []
    for section in re.split(r"^## ", text, flags=re.MULTILINE):
        if section.split("\n", 1)[0].strip() not in SECTIONS:
            continue
        for block in re.findall(r"^```bash\n(.*?)^```", section, flags=re.MULTILINE | re.DOTALL):
            for line in re.sub(r"\s*\\\n\s*", " ", block).splitlines():
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
    """What runs for one README command: SUBSTITUTIONS, then RUN_DEFAULTS (`{lcm}` and `{port}`
    are filled in as it runs: they differ from one test process to the next)."""
    for pattern, replacement, _why in SUBSTITUTIONS:
        command = re.sub(pattern, replacement, command)
    result = []
    for each in command.split("\n"):
        if each.startswith("viewer-bridge run"):
            missing = [option for marker, option in RUN_DEFAULTS if marker not in each]
            each = " ".join(["viewer-bridge run", *missing, each.removeprefix("viewer-bridge run").strip()]).strip()
        result.append(each)
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
    both = f"{sys.executable} {CONTACT_SCENE} '{url}' 0.5 && {sys.executable} {SCENE} '{url}' {folder}"
    record_log(folder / "drake.lcmlog", url, ["bash", "-c", both])
    (folder / "mappings").mkdir()
    return folder


def test_the_readme_lists_commands() -> None:
    assert len(CASES) >= 15, [case.values for case in CASES]  # a README whose list was not found


@pytest.mark.parametrize(("command", "exit_code"), CASES)
def test_a_readme_command_exits_as_the_readme_says(command: str, exit_code: int, folder: Path) -> None:
    path = f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"  # the venv's viewer-bridge
    command = command.replace("{lcm}", LCM).replace("{port}", str(PORT))
    process = subprocess.Popen(
        ["bash", "-c", f"exec {command}"], cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PATH": path, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    ready = next((line for start, line in SERVERS.items() if command.startswith(start)), None)
    if ready is not None:
        assert process.stderr is not None
        logged = list(_lines_until(process.stderr, ready))
        assert ready in "".join(logged), "".join(logged)
        process.send_signal(signal.SIGINT)  # Ctrl-C
    stdout, stderr = process.communicate(timeout=180)
    assert process.returncode == exit_code, stderr[-3000:]
    assert "Traceback" not in stderr, stderr[-3000:]


def _lines_until(stream: IO[str], text: str) -> Iterator[str]:
    """The stream's lines up to the first that holds `text` (all of them if it never comes)."""
    for line in stream:
        yield line
        if text in line:
            return
