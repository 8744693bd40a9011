"""Progress on a pipe: nothing for quick work, then one line per tenth (or every few seconds
when the total is not known), on a clock the test moves."""

from __future__ import annotations

import io

import pytest

from viewer_bridge.util import progress as progress_module
from viewer_bridge.util.progress import EVERY_S, QUIET_S, progress


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> Clock:
    clock = Clock()
    monkeypatch.setattr(progress_module.time, "monotonic", clock)
    return clock


def test_quick_work_says_nothing_and_long_work_a_line_per_tenth(clock: Clock) -> None:
    out = io.StringIO()
    with progress("viewer-bridge convert", "converting", 100, lambda done: f"{done} of 100 events",
                  terminal=False, stream=out) as advance:  # fmt: skip
        advance(30)  # quick: nothing
        clock.now += QUIET_S
        advance(5)
        advance(1)  # the same tenth
        for _ in range(64):
            advance(1)
    said = [
        f"viewer-bridge convert: converting: {tenth}%: {tenth} of 100 events (2 s)"
        for tenth in range(40, 101, 10)
    ]
    assert out.getvalue().splitlines() == [
        "viewer-bridge convert: converting: 30%: 35 of 100 events (2 s)",
        *said,
    ]


def test_without_a_total_a_line_every_few_seconds(clock: Clock) -> None:
    out = io.StringIO()
    with progress("viewer-bridge convert", "converting", None, lambda done: f"{done:,} messages",
                  terminal=False, stream=out) as advance:  # fmt: skip
        advance(1000)
        clock.now += QUIET_S + EVERY_S
        advance(1000)
        advance(1000)  # too soon after the last line
        clock.now += EVERY_S
        advance(1000)
    assert out.getvalue().splitlines() == [
        "viewer-bridge convert: converting: 2,000 messages (7 s)",
        "viewer-bridge convert: converting: 4,000 messages (12 s)",
    ]


def test_steps_on_a_pipe_are_plain_lines_as_they_come() -> None:
    from viewer_bridge.util.progress import steps

    out = io.StringIO()
    with steps(terminal=False, stream=out) as told:
        told.say("building tf2_msgs (2 types) into /venv")
        with told.paused():
            pass
        told.say("built tf2_msgs in 9.7 s")
    assert out.getvalue() == "building tf2_msgs (2 types) into /venv\nbuilt tf2_msgs in 9.7 s\n"


def test_steps_on_a_terminal_print_each_line_and_leave_no_spinner() -> None:
    from viewer_bridge.util.progress import steps

    out = io.StringIO()
    with steps(terminal=True, stream=out) as told:
        told.say("building tf2_msgs (2 types) into /venv")
        told.say("built tf2_msgs in 9.7 s")
    lines = [line for line in out.getvalue().splitlines() if line.strip()]
    assert "building tf2_msgs (2 types) into /venv" in lines[0] and "built tf2_msgs in 9.7 s" in lines[1]


def test_a_part_of_known_size_on_a_pipe_is_a_line_per_tenth_after_the_quiet_seconds(clock: Clock) -> None:
    from viewer_bridge.util.progress import steps

    out = io.StringIO()
    with steps(terminal=False, stream=out) as told:
        told.say("building a_msgs (2 types) into /venv")
        told.part("building a_msgs", 1, 20, lambda done: f"{done} of 20 build steps")  # quick: nothing
        clock.now += QUIET_S
        for done in range(2, 21):
            told.part("building a_msgs", done, 20, lambda done: f"{done} of 20 build steps")
        told.say("built a_msgs in 2.0 s")
    tenths = [
        f"building a_msgs: {tenth * 10}%: {tenth * 2} of 20 build steps (2 s)" for tenth in range(1, 11)
    ]
    assert out.getvalue().splitlines() == [
        "building a_msgs (2 types) into /venv",
        *tenths,
        "built a_msgs in 2.0 s",
    ]


def test_a_part_on_a_terminal_is_a_bar_that_leaves_nothing_behind() -> None:
    from viewer_bridge.util.progress import steps

    out = io.StringIO()
    with steps(terminal=True, stream=out) as told:
        told.say("building a_msgs (2 types) into /venv")
        for done in range(1, 21):
            told.part("building a_msgs", done, 20, lambda done: f"{done} of 20 build steps")
        told.say("built a_msgs in 2.0 s")
    lines = [line for line in out.getvalue().splitlines() if line.strip()]
    assert "building a_msgs (2 types) into /venv" in lines[0] and "built a_msgs in 2.0 s" in lines[1]
