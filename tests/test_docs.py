"""The documentation, run: every shell command and every Python block of README.md and of each
guide in docs/, top to bottom, as a user would run them; and the site, built with strict checks.

The commands come from the pages themselves: every line of their fenced `bash` and `sh` blocks
(a `\\` continuation joined to its next line, the trailing comment removed, comment-only lines
skipped), each run through bash in one temporary folder shared by every page, with the venv's
`viewer-bridge` first on PATH and this test's own LCM bus as `LCM_DEFAULT_URL` (which LCM's tools
and the bridge read when no URL is given). The folder starts with `drake.lcmlog`, written as
docs/recording.md says: the `contacts` example (unsuffixed channels and CONTACT_RESULTS), then
the `shapes` example (every shape, role-suffixed channels) appended; and the README's `demo.lcmlog`.

What the test changes in the commands, and why, is all in SUBSTITUTIONS (applied in order),
RUN_DEFAULTS and SERVERS; what it cannot run here is NOT_RUN, each with its reason; every other
character is the page's. A command must exit as its page says: 0, unless its own comment names
another code (`# ... exit 2`); a server must say it is ready and then stop on Ctrl-C (SIGINT)
with 0. No command may print a traceback. A page's Python blocks run in order in one
interpreter, in the same folder.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import pytest

from tests.claims import tcp_port
from tests.conftest import lcm_url

pytestmark = pytest.mark.slow
ROOT = Path(__file__).parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LCM = lcm_url(31)  # this test's own LCM bus: the default one is shared by the machine


PORT = tcp_port(98)  # for servers the pages run on a fixed port
ZENOH_PORT = tcp_port(99)  # for the Zenoh router the Zenoh guide opens

# (what the page says, as a regex; what runs instead (`{lcm}`, `{port}`, `{zenoh_port}` filled in
# as it runs), a newline between several commands; why). Applied to Python blocks too.
SUBSTITUTIONS: list[tuple[str, str, str]] = [
    (r"udpm://239\.255\.76\.67:766[78]\?ttl=0", "{lcm}", "this test's own bus"),
    (r"\[--url URL\] \[--rate 60\] \[--duration S\]", "--url '{lcm}' --rate 60 --duration 1",
     "the optional arguments, given"),
    (r"--duration (5|10)\b", "--duration 1", "shorter"),
    (r"foxglove\.port=9000", "foxglove.port=0", "any free port: other bridges may be running here"),
    (r"\bviewer-bridge play (?!.*foxglove\.port=)", "viewer-bridge play --set foxglove.port=0 ",
     "any free port: other bridges may be running here"),
    (r"127\.0\.0\.1:7447", "127.0.0.1:{zenoh_port}", "a free port: a Zenoh router may be running here"),
    (r"zenoh\.mode=router --duration", "zenoh.mode=router --set 'zenoh.listen=[tcp/127.0.0.1:{zenoh_port}]' --duration",
     "a free port for the bridge as a router (it listens on 7447 by default): a Zenoh router may be running here"),
    (r"\[-c CONFIG\]", "-c builtin:default", "the optional argument, given"),
    (r"\[--host 127\.0\.0\.1\] \[--port 8000\] \[--max-upload BYTES\]",
     "--host 127.0.0.1 --port {port} --max-upload 1000000", "the optional arguments, given; a free port"),
    (r"\./my_lcmtypes", str(ROOT / "tests" / "translators" / "lcm_corpus"), "a lab's types: the tests' corpus"),
    (r"\bmy_lab_lcm_msgs\b", "vbtest_lab_lcm_msgs", "the package of the tests' corpus (package vbtest_lab)"),
    (r"\binstall/my_robot_msgs/share/my_robot_msgs/msg\b", str(ROOT / "tests/lcmcodec/ros_msgs/my_robot/msg"),
     "a workspace's installed .msg files: the tests' custom package"),
    (r"\bmy_(lab|geo)\.", "vbtest_\\1.", "the LCM packages of the tests' corpus"),
    (r"rerun\.serve=true", "rerun.serve=true --set rerun.grpc_port=0 --set rerun.web_port=0",
     "free ports: a viewer or another bridge may be serving here"),
    (r"\[--size 640x480\] \[--fov 45\] \[--camera EX,EY,EZ,TX,TY,TZ\]",
     "--size 640x480 --fov 45 --camera 2,2,1.5,0,0,0", "the optional arguments, given"),
    (r"^(viewer-bridge snapshot \S+) out\.png (.*)\[--image color\|label\|depth\](.*)$",
     "\\1 color.png \\2--image color\\3\n\\1 label.png \\2--image label\\3\n\\1 depth.png \\2--image depth\\3",
     "each image, each into a file of its own"),
]  # fmt: skip

# What every `viewer-bridge run` gets unless it already names it (a run would go on until Ctrl-C
# and take the Foxglove port 8765), inserted right after `run` so that `--ros-args ...` stays
# last: (what shows it is named, the option).
RUN_DEFAULTS = [("--duration", "--duration 2"), ("foxglove.port=", "--set foxglove.port=0")]

# Commands that serve until Ctrl-C, by how they start: the line each logs once it is ready.
SERVERS = {"viewer-bridge serve-render": "render server on", "viewer-bridge play": " running ("}

# Commands not run here: (a regex their line matches, why). Each is run elsewhere or is what CI does.
NOT_RUN: list[tuple[str, str]] = [
    (r"^\./dev (run|test)\b", "sets up .venv from the clone: CI runs `./dev test` on a fresh machine"),
    (r"pip install", "installs the clone into a venv: what `./dev` does on a fresh machine"),
    (r"^(RMW_IMPLEMENTATION=\S+ )?(ros2|rviz2)\b", "ROS 2's command line and RViz are not in the venv "
     "(rclpy wheels only); tests/transports/zenoh/test_transport.py checks the same as an rmw_zenoh peer"),
    (r"pydrake\.visualization\.meldis", "a viewer that serves until stopped"),
    (r"zenoh-tls\.json5", "needs a TLS router and its certificates"),
    (r"\bgz topic\b|gz_peer/|gz13/env\.sh|gz_interop\.py",
     "Gazebo Harmonic's tools are built from source (docs/GZ_PEER.md): bench/gz_interop.py runs them"),
    (r"ign-transport-topic -(e|p)\b", "needs a bridge running at the same time: tests/transports/test_ign.py "
     "runs the same commands against one"),
    (r"&\s*$", "starts a background process for the lines after it (docs/GZ_PEER.md)"),
    (r"\bcolcon build\b", "builds a workspace against a ROS 2 install (none here: the venv has its wheels): "
     "tests/ros_build/test_interfaces.py builds generated packages and a C++ one with colcon against the wheels"),
    (r"^rerun\b", "opens Rerun's viewer window: tests/transports/test_rerun_web.py opens its web viewer in Chromium"),
]  # fmt: skip


def blocks(text: str, languages: tuple[str, ...]) -> list[str]:
    """The fenced blocks of these languages, in order (indented fences too: in a list item)."""
    fence = "|".join(languages)
    return [
        "\n".join(line[len(indent):] for line in body.splitlines())
        for indent, body in re.findall(rf"^( *)```(?:{fence})\n(.*?)^\1```", text, flags=re.MULTILINE | re.DOTALL)
    ]  # fmt: skip


def page_commands(text: str) -> list[str]:
    """The command lines of a page's shell blocks, top to bottom."""
    commands: list[str] = []
    for block in blocks(text, ("bash", "sh")):
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


def substituted(text: str) -> str:
    for pattern, replacement, _why in SUBSTITUTIONS:
        text = re.sub(pattern, replacement, text, flags=re.MULTILINE)
    return text


def adapted(command: str) -> list[str]:
    """What runs for one command: SUBSTITUTIONS, then RUN_DEFAULTS after every `viewer-bridge run`."""
    result = []
    for each in substituted(command).split("\n"):
        missing = [option for marker, option in RUN_DEFAULTS if marker not in each]
        result.append(
            re.sub(r"\bviewer-bridge run\b(?! --print)", " ".join(["viewer-bridge run", *missing]), each)
        )
    return result


def expected_exit(comment: str) -> int:
    found = re.search(r"\bexit (\d+)", comment)
    return int(found.group(1)) if found else 0


def not_run(command: str) -> str | None:
    return next((why for pattern, why in NOT_RUN if re.search(pattern, command)), None)


def _page(path: Path) -> str:
    return str(path.relative_to(ROOT))


CASES = [
    pytest.param(_page(page), run, expected_exit(comment), id=f"{_page(page)}: {run}")
    for page in PAGES
    for line in page_commands(page.read_text())
    for command, comment in [without_comment(line)]
    if not_run(command) is None
    for run in adapted(command)
]
PYTHON_PAGES = [_page(page) for page in PAGES if blocks(page.read_text(), ("python",))]


def environment() -> dict[str, str]:
    path = f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"  # the venv's viewer-bridge first
    return {**os.environ, "PATH": path, "PYTHONUNBUFFERED": "1", "LCM_DEFAULT_URL": LCM}


def filled(text: str) -> str:
    return text.replace("{lcm}", LCM).replace("{port}", str(PORT)).replace("{zenoh_port}", str(ZENOH_PORT))


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The pages' folder, with `drake.lcmlog` recorded as docs/recording.md says, and the README
    tour's `demo.lcmlog` (so that any test here runs alone too)."""
    folder = tmp_path_factory.mktemp("docs")
    subprocess.run([sys.executable, "-m", "viewer_bridge.cli.main", "demo", "--url", "file://demo.lcmlog?mode=w",
                    "--duration", "1"], cwd=folder, check=True, timeout=300, capture_output=True)  # fmt: skip
    for name, mode in (("contacts", "w"), ("shapes", "a")):
        subprocess.run([sys.executable, "-m", "viewer_bridge.cli.main", "example", name, "--duration", "1",
                        "--lcm-url", f"file://drake.lcmlog?mode={mode}"], cwd=folder, check=True, timeout=300)  # fmt: skip
    return folder


def test_the_pages_list_commands() -> None:
    assert len(CASES) >= 40, [case.values for case in CASES]  # pages whose blocks were not found
    assert {case.values[0] for case in CASES} >= {"README.md", "docs/recording.md", "docs/ros2.md"}


def test_what_is_not_run_is_few_and_said_why() -> None:
    skipped = [(_page(page), line) for page in PAGES for line in page_commands(page.read_text())
               if not_run(without_comment(line)[0])]  # fmt: skip
    assert len(skipped) <= 27, skipped


@pytest.mark.parametrize(("page", "command", "exit_code"), CASES)
def test_a_command_exits_as_its_page_says(page: str, command: str, exit_code: int, folder: Path) -> None:
    command = filled(command)
    ready = next((line for start, line in SERVERS.items() if command.startswith(start)), None)
    process = subprocess.Popen(  # a server is exec'd, so that Ctrl-C reaches it and not bash
        ["bash", "-c", f"exec {command}" if ready else command], cwd=folder, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, env=environment(),
    )  # fmt: skip
    if ready is not None:
        assert process.stderr is not None
        logged = list(_lines_until(process.stderr, ready))
        assert ready in "".join(logged), "".join(logged)
        process.send_signal(signal.SIGINT)  # Ctrl-C
    stdout, stderr = process.communicate(timeout=300)
    assert process.returncode == exit_code, stderr[-3000:]
    assert "Traceback" not in stderr, stderr[-3000:]


@pytest.mark.parametrize("page", PYTHON_PAGES)
def test_a_pages_python_runs(page: str, folder: Path) -> None:
    code = "\n\n".join(filled(substituted(block)) for block in blocks((ROOT / page).read_text(), ("python",)))
    done = subprocess.run([sys.executable, "-c", code], cwd=folder, capture_output=True, text=True, timeout=300,
                          env=environment())  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]


def test_the_site_builds_with_every_link_and_anchor_checked(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert "ten-minute tour" in (tmp_path / "site" / "index.html").read_text()  # the home page is the README


def _lines_until(stream: IO[str], text: str) -> Iterator[str]:
    """The stream's lines up to the first that holds `text` (all of them if it never comes)."""
    for line in stream:
        yield line
        if text in line:
            return
