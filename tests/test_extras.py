"""A missing extra is one line naming the pip command that installs it, whichever part needs it:
a transport when the router starts, the renderer, a converter. Each case runs in a process where
the extra's module cannot be imported (`sys.modules[name] = None`, as if never installed)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import lcm_url
from viewer_bridge import convert
from viewer_bridge.errors import BridgeError, MissingExtra
from viewer_bridge.util.extras import EXTRAS, missing, require

# (the module made missing, the command line's arguments, the extra the message must name)
COMMANDS = [
    ("rclpy", ["run", "-c", "builtin:default", "--duration", "1", "--set", "foxglove.port=0"], "ros"),
    ("zmq", ["run", "-c", "builtin:ign", "--duration", "1"], "ign"),
    (
        "foxglove",
        ["run", "-c", "builtin:foxglove", "--duration", "1", "--set", "foxglove.port=0"],
        "foxglove",
    ),
    ("zenoh", ["run", "-c", "builtin:zenoh", "--duration", "1"], "zenoh"),
    ("moderngl", ["serve-render", "--port", "0"], "render"),
]


@pytest.mark.parametrize(("module", "arguments", "extra"), COMMANDS, ids=[case[0] for case in COMMANDS])
def test_a_command_without_its_extra_says_which_to_install(
    module: str, arguments: list[str], extra: str
) -> None:
    code = (f"import sys; sys.modules[{module!r}] = None; from viewer_bridge.cli.main import main; "
            "sys.exit(main(sys.argv[1:]))")  # fmt: skip
    result = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            *arguments,
            *(["--lcm-url", lcm_url(42)] if arguments[0] == "run" else []),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    last = result.stderr.strip().splitlines()[-1]  # after any log line (e.g. LCM's buffer size warning)
    assert last.startswith(f"viewer-bridge {arguments[0]}: "), result.stderr
    assert last.endswith(f"needs {module}, not installed: pip install 'viewer-bridge[{extra}]'"), (
        result.stderr
    )
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    ("module", "call"),
    [
        ("foxglove_schemas_protobuf", "convert.load_to_scene_update(b'')"),
        ("rclpy", "convert.cdr_to_rclpy(b'', 'geometry_msgs/msg/PoseArray')"),
        ("visualization_msgs", "from viewer_bridge.formats.ros.messages import STORE, to_rclpy\n"
                               "to_rclpy(STORE.types['visualization_msgs/msg/MarkerArray'](markers=[]))"),
    ],
)  # fmt: skip
def test_a_converter_without_its_extra_says_which_to_install(module: str, call: str) -> None:
    code = f"import sys; sys.modules[{module!r}] = None\nfrom viewer_bridge import convert\n{call}"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "viewer_bridge.errors.MissingExtra: " in result.stderr, result.stderr
    assert f"needs {module}, not installed: pip install 'viewer-bridge[{EXTRAS[module]}]'" in result.stderr


def test_require_imports_or_names_the_extra() -> None:
    assert require("json", "a test").__name__ == "json"
    with pytest.raises(
        MissingExtra, match=r"^a test needs moderngl_x, not installed: pip install 'viewer-bridge\[all\]'$"
    ):
        require("moderngl_x", "a test")
    error = missing(ModuleNotFoundError("no zmq", name="zmq.backend"), "the ign transport")
    assert isinstance(error, BridgeError) and error.extra == "ign" and error.module == "zmq"
    assert convert.__name__ == "viewer_bridge.convert"


def test_the_built_in_config_runs_with_the_ros_and_foxglove_extras_alone() -> None:
    """`viewer-bridge run` on its default config: ROS 2 and Foxglove routes, no ign, zenoh or renderer."""
    code = (
        "import sys\nfor name in ('zmq', 'zenoh', 'xxhash', 'moderngl'): sys.modules[name] = None\n"
        "from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))"
    )
    arguments = ["run", "--demo", "--duration", "2", "--lcm-url", lcm_url(43), "--set", "foxglove.port=0"]
    result = subprocess.run(
        [sys.executable, "-c", code, *arguments], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    assert " route poses: in " in result.stderr and "Traceback" not in result.stderr, result.stderr


def test_the_built_in_config_with_ros_alone_leaves_its_foxglove_routes_out_saying_so() -> None:
    """`[ros]` (tf2_msgs built, as here) without `[foxglove]`: `viewer-bridge run` serves ROS 2, and
    says in one line what it left out and which extra brings it; a config named with -c stays as
    strict as before."""
    code = (f"import sys\nfor name in {blocked_but('ros')!r}: sys.modules[name] = None\n"
            "from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))")  # fmt: skip
    arguments = ["run", "--demo", "--duration", "4", "--lcm-url", lcm_url(46)]
    result = subprocess.run(
        [sys.executable, "-c", code, *arguments], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    (said,) = [line for line in result.stderr.splitlines() if "left out" in line]
    assert said.endswith("viewer-bridge: the built-in config's 6 Foxglove routes left out: they need foxglove, "
                         "not installed: pip install 'viewer-bridge[foxglove]'"), said  # fmt: skip
    assert "ROS 2 node /viewer_bridge)" in result.stderr and "Traceback" not in result.stderr, result.stderr
    named = subprocess.run([sys.executable, "-c", code, *arguments[:1], "-c", "builtin:default", *arguments[1:]],
                           capture_output=True, text=True, timeout=120)  # fmt: skip
    assert named.returncode == 2 and named.stderr.strip().splitlines()[-1].endswith(
        "needs foxglove, not installed: pip install 'viewer-bridge[foxglove]'"
    ), named.stderr


def blocked_but(extra: str) -> list[str]:
    """The modules of every extra but `extra`: what a venv with the core and that extra lacks."""
    return sorted(module for module, owner in EXTRAS.items() if owner != extra)


# (the one extra installed, the command line's arguments, a line the command prints when it works)
ONE_EXTRA = [
    ("foxglove", ["run", "-c", "builtin:foxglove", "--demo", "--duration", "3", "--set", "foxglove.port=0"],
     " routes running ("),
    ("foxglove", ["convert", "LOG", "OUT"], "wrote OUT: "),
    ("zenoh", ["run", "-c", "builtin:zenoh", "--duration", "1"], " routes running ("),
]  # fmt: skip


@pytest.mark.parametrize(
    ("extra", "arguments", "said"), ONE_EXTRA, ids=[" ".join(case[1][:3]) for case in ONE_EXTRA]
)
def test_one_extra_alone_runs_its_built_in_config(
    tmp_path: Path, extra: str, arguments: list[str], said: str
) -> None:
    """No route needs a module of an extra the user did not ask for (e.g. the Rerun schema's pyarrow)."""
    from tests.cli.test_cli import demo_log

    names = {"LOG": str(demo_log(tmp_path / "demo.lcmlog", 10)), "OUT": str(tmp_path / "x.mcap")}
    arguments = [names.get(word, word) for word in arguments]
    if arguments[0] == "run":
        arguments += ["--lcm-url", lcm_url(44)]
    code = (
        f"import sys\nfor name in {blocked_but(extra)!r}: sys.modules[name] = None\n"
        "from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))"
    )
    result = subprocess.run(
        [sys.executable, "-c", code, *arguments], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    assert said.replace("OUT", names["OUT"]) in result.stdout + result.stderr, result
    assert "not installed" not in result.stderr and "Traceback" not in result.stderr, result.stderr


# `run --demo` with no -c, in a venv of the core and one extra: the one line said, what then runs.
ONE_EXTRA_DEMO = [
    ("foxglove", "the built-in config's 17 ROS 2 routes left out: they need rclpy, not installed: "
                 "pip install 'viewer-bridge[ros]'", r" route foxglove_\w+: in [1-9]|waiting for a subscriber: foxglove_"),
    ("zenoh", "the built-in config's routes need rclpy and foxglove, not installed: pip install "
              "'viewer-bridge[ros,foxglove]'; running -c builtin:zenoh, the built-in config of what is installed",
     r" route poses: in [1-9]\d* out [1-9]"),
    ("ign", "running -c builtin:ign, the built-in config of what is installed", r" route pose_v: in [1-9]\d* out [1-9]"),
    ("rerun", "running -c builtin:rerun, the built-in config of what is installed", r"6 routes running \("),
]  # fmt: skip


@pytest.mark.parametrize(("extra", "said", "works"), ONE_EXTRA_DEMO, ids=[case[0] for case in ONE_EXTRA_DEMO])
def test_run_demo_with_one_extra_runs_what_it_can_and_says_what_it_left_out(
    extra: str, said: str, works: str
) -> None:
    """One rule for every extra: the built-in config's routes that extra runs (or, with none left,
    the built-in config of that extra), and one line naming what was left out and the extra that adds it."""
    import re

    code = (f"import sys\nfor name in {blocked_but(extra)!r}: sys.modules[name] = None\n"
            "from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))")  # fmt: skip
    arguments = ["run", "--demo", "--duration", "3", "--stats-period", "1", "--lcm-url", lcm_url(47)]
    result = subprocess.run(
        [sys.executable, "-c", code, *arguments], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    assert [line for line in result.stderr.splitlines() if "not installed" in line] == [
        next(line for line in result.stderr.splitlines() if line.endswith(said))
    ], result.stderr
    assert re.search(works, result.stderr) and "Traceback" not in result.stderr, result.stderr


def test_run_demo_with_no_extra_names_the_extras_in_one_line() -> None:
    code = (f"import sys\nfor name in {sorted(EXTRAS)!r}: sys.modules[name] = None\n"
            "from viewer_bridge.cli.main import main; sys.exit(main(sys.argv[1:]))")  # fmt: skip
    result = subprocess.run([sys.executable, "-c", code, "run", "--demo", "--duration", "3", "--lcm-url", lcm_url(48)],
                            capture_output=True, text=True, timeout=120)  # fmt: skip
    assert result.returncode == 2 and not result.stdout, result
    assert result.stderr == (
        "viewer-bridge run: no built-in config can run: this install has none of their extras: pip install "
        "'viewer-bridge[ros]' or 'viewer-bridge[foxglove]' for the default config, or [zenoh] for -c "
        "builtin:zenoh, [rerun] for -c builtin:rerun, [ign] for -c builtin:ign\n"
    )
