"""`viewer-bridge play`'s keys, on a terminal: space pauses and plays, left and right step one
draw back and forth (paused there, the world at that draw re-sent), + and - change the speed.
Each key's effect is said in one line with the position (above the route table), and Foxglove
clients get the new state as they do for each other's requests.

The terminal is put in cbreak mode (keys come one at a time, unechoed; Ctrl-C still interrupts)
while `play` runs, and restored when it ends, whatever ends it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import sys
import termios
import threading
import tty
from collections.abc import Iterator

from viewer_bridge.transports.lcm_playback import LogPlayer
from viewer_bridge.transports.playback import PlaybackRequest, PlaybackState, Status

log = logging.getLogger("viewer_bridge")

DRAWS = "DRAKE_VIEWER_DRAW.*"  # what left and right step through
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)  # what + and - step through
RIGHT, LEFT = "\x1b[C", "\x1b[D"  # the arrow keys' escape sequences (ANSI cursor keys)
HELP = "keys: space play/pause, left/right one draw back/forth, +/- speed"


def on_a_terminal() -> bool:
    return sys.stdin.isatty() and sys.stdout.isatty()


class Keys:
    """The keys read on a thread of their own from a terminal's `fd`, applied to `player`."""

    def __init__(self, player: LogPlayer, fd: int) -> None:
        self.player = player
        self._fd = fd
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="play keys", daemon=True)

    def start(self) -> None:
        """Read keys; the end of the log is said, and `play` stays (a key may step back)."""
        log.info("viewer-bridge play: %s", HELP)
        self.player.watch(
            lambda state: log.info("viewer-bridge play: %s", self.position(state)), lambda _: None
        )
        self._thread.start()

    def _run(self) -> None:
        pending = ""
        while not self._stop.is_set():
            ready, _, _ = select.select([self._fd], [], [], 0.1)
            if not ready:
                pending = ""  # a lone escape, or a sequence cut short: dropped
                continue
            data = os.read(self._fd, 64)
            if not data:
                return  # the terminal went away
            pending += data.decode("utf-8", "replace")
            pending = self._apply_all(pending)

    def _apply_all(self, text: str) -> str:
        """Apply each whole key in `text`; returns what may be the start of an escape sequence."""
        while text:
            if text.startswith("\x1b"):
                if len(text) < 3:
                    return text
                key, text = text[:3], text[3:]
            else:
                key, text = text[0], text[1:]
            self.press(key)
        return ""

    def press(self, key: str) -> None:
        player = self.player
        state = player.state()
        if key == " ":
            play = state.status != Status.PLAYING
            answer = player.request(PlaybackRequest(play=play, speed=state.speed), tell=True)
        elif key in (RIGHT, LEFT):
            answer = player.step(1 if key == RIGHT else -1, DRAWS)
        elif key in "+=-_":
            faster = key in "+="
            speeds = [speed for speed in SPEEDS if (speed > state.speed if faster else speed < state.speed)]
            if not speeds:
                return
            speed = speeds[0] if faster else speeds[-1]
            playing = state.status == Status.PLAYING
            answer = player.request(PlaybackRequest(play=playing, speed=speed), tell=True)
        else:
            return
        if answer.note is not None:
            log.warning("viewer-bridge play: %s", answer.note)
        log.info("viewer-bridge play: %s", self.position(answer.state))

    def position(self, state: PlaybackState) -> str:
        first_ns, last_ns = self.player.range_ns
        return (f"{state.status.value} at {(state.time_ns - first_ns) / 1e9:.3f} s of "
                f"{(last_ns - first_ns) / 1e9:.3f} s, {state.speed:g}x")  # fmt: skip

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1)


@contextlib.contextmanager
def keys(player: LogPlayer) -> Iterator[Keys | None]:
    """The keys of the terminal `play` runs on (None when stdin or stdout is no terminal), the
    terminal restored at the end."""
    if not on_a_terminal():
        yield None
        return
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    reader = Keys(player, fd)
    try:
        reader.start()
        yield reader
    finally:
        reader.stop()
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
