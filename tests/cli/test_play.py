"""`viewer-bridge play` end to end: the bridge as a process playing a log to its Foxglove server,
driven by a client written here from the Foxglove WebSocket protocol (binary opcode 3 playback
control requests; from the server opcode 5 playback states and opcode 2 time, JSON serverInfo
and status), and an LCM subscriber on `--lcm-out`."""

from __future__ import annotations

import contextlib
import json
import os
import re
import struct
import subprocess
import sys
import termios
import threading
import time
from pathlib import Path
from typing import Any

import drake as drake_lcmtypes
import pytest
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from websockets.sync.client import ClientConnection, connect

from tests.conftest import lcm_url
from tests.peers import BridgeProcess, wait_for
from tests.test_router import LcmRecorder
from viewer_bridge.transports.lcm import LcmEvent, read_log

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
WAIT = 60.0
PLAYING, PAUSED, ENDED = 0, 1, 3


class PlayProcess(BridgeProcess):
    """`viewer-bridge play` in a process of its own, its Foxglove server on a free port; its log lines kept."""

    stop_s = 30.0  # it closes its player and index too

    def __init__(self, *args: str) -> None:
        super().__init__(*args, subcommand="play")

    def port(self) -> int:
        deadline = time.monotonic() + WAIT
        while time.monotonic() < deadline:
            for line in list(self.lines):
                if match := re.search(r"running \(.*ws://127\.0\.0\.1:(\d+)", line):
                    return int(match.group(1))
            assert self.process.poll() is None, self.lines
            time.sleep(0.05)
        raise AssertionError(f"no start-up line: {self.lines}")


class PlaybackClient:
    """A Foxglove client that drives playback: it sends opcode 3 requests and keeps, in arrival
    order, every opcode 5 state, opcode 2 time and message (with its log time) it receives."""

    def __init__(self, port: int) -> None:
        self._connection = connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"],  # type: ignore[list-item]
                                   ping_interval=None, max_queue=None)  # fmt: skip
        self.ws: ClientConnection = self._connection.__enter__()
        self.info: dict[str, Any] = {}
        self.channels: dict[str, int] = {}  # topic -> channel id
        self.statuses: list[dict[str, Any]] = []
        # ("state", (status, time ns, speed, did_seek, request id)) | ("time", ns) | (topic, (log time, payload))
        self.seen: list[tuple[str, Any]] = []
        self._topics: dict[int, str] = {}
        self._sent_at: dict[str, int] = {}  # request id -> how much had been seen when it was sent

    def pump(self, until: Any, seconds: float = WAIT) -> bool:
        deadline = time.monotonic() + seconds
        while not until():
            if time.monotonic() > deadline:
                return False
            try:
                frame = self.ws.recv(timeout=max(0.01, deadline - time.monotonic()))
            except TimeoutError:
                continue
            if isinstance(frame, str):
                message = json.loads(frame)
                if message["op"] == "serverInfo":
                    self.info = message
                elif message["op"] == "advertise":
                    self.channels.update({channel["topic"]: channel["id"] for channel in message["channels"]})
                elif message["op"] == "status":
                    self.statuses.append(message)
            elif frame[0] == 0x01:  # message data: u32 subscription, u64 log time, payload
                subscription, log_time = struct.unpack_from("<IQ", frame, 1)
                self.seen.append((self._topics[subscription], (log_time, bytes(frame[13:]))))
            elif frame[0] == 0x02:  # time
                self.seen.append(("time", struct.unpack_from("<Q", frame, 1)[0]))
            elif frame[0] == 0x05:  # playback state
                status, now, speed, did_seek, length = struct.unpack_from("<BQfBI", frame, 1)
                request_id = bytes(frame[19 : 19 + length]).decode()
                self.seen.append(("state", (status, now, speed, bool(did_seek), request_id)))
        return True

    def subscribe(self, topic: str) -> None:
        assert self.pump(lambda: topic in self.channels), self.channels
        subscription = len(self._topics) + 1
        self._topics[subscription] = topic
        self.ws.send(
            json.dumps(
                {
                    "op": "subscribe",
                    "subscriptions": [{"id": subscription, "channelId": self.channels[topic]}],
                }
            )
        )

    def request(self, play: bool, speed: float, seek_ns: int | None, request_id: str) -> tuple[Any, ...]:
        """Send a playback control request; the state that answers it."""
        encoded = request_id.encode()
        self._sent_at[request_id] = len(self.seen)
        self.ws.send(
            struct.pack(
                "<BBfBQI", 0x03, 0 if play else 1, speed, seek_ns is not None, seek_ns or 0, len(encoded)
            )
            + encoded
        )
        assert self.pump(lambda: self.answer(request_id) is not None), self.seen[-5:]
        answer = self.answer(request_id)
        assert answer is not None
        return answer

    def answer(self, request_id: str) -> tuple[Any, ...] | None:
        return next((state for kind, state in self.seen if kind == "state" and state[4] == request_id), None)

    def after(self, request_id: str, topic: str) -> list[Any]:
        """What arrived on `topic` (or "time") since the request `request_id` was sent."""
        return [item for kind, item in self.seen[self._sent_at[request_id] :] if kind == topic]

    def close(self) -> None:
        self._connection.__exit__(None, None, None)


def ns(event: LcmEvent) -> int:
    return event.timestamp_us * 1000


def sim_ms(transforms: bytes) -> int:
    message = FrameTransforms()
    message.ParseFromString(transforms)
    stamp = message.transforms[0].timestamp
    return round(stamp.seconds * 1000 + stamp.nanos / 1e6)


@pytest.fixture(scope="module")
def demo_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three seconds of the demo scene, as `viewer-bridge demo` records it."""
    path = tmp_path_factory.mktemp("play") / "demo.lcmlog"
    command = [
        sys.executable,
        "-m",
        "viewer_bridge.cli.main",
        "demo",
        "--url",
        f"file://{path}?mode=w",
        "--duration",
        "3",
    ]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, timeout=120)
    return path


def test_foxglove_drives_the_playback_and_lcm_follows(demo_log: Path) -> None:
    events = list(read_log(demo_log))
    draws = [event for event in events if event.channel == "DRAKE_VIEWER_DRAW"]
    first, last = ns(events[0]), ns(events[-1])
    url = lcm_url(2)
    recorder = LcmRecorder(url)
    # Transforms stamped with sim time (`time: sim`), which tells the draws apart; log times stay the timeline's.
    bridge = PlayProcess(
        str(demo_log), "-c", "builtin:foxglove", "--paused", "--lcm-out", url, "--set", "time=sim"
    )
    client = None
    try:
        client = PlaybackClient(bridge.port())
        assert client.pump(lambda: bool(client.info)), client.info
        assert {"playbackControl", "time"} <= set(client.info["capabilities"])
        start, end = client.info["dataStartTime"], client.info["dataEndTime"]
        assert (start["sec"] * 10**9 + start["nsec"], end["sec"] * 10**9 + end["nsec"]) == (first, last)
        # paused at the start: the scene alone (no draw yet at the log's first instant)
        assert wait_for(lambda: recorder.messages.get("DRAKE_VIEWER_LOAD_ROBOT", []) == [events[0].data])
        assert "DRAKE_VIEWER_DRAW" not in recorder.messages

        # seek to the middle while paused: the world at that instant, on Foxglove and on LCM
        middle = draws[len(draws) // 2]
        state = client.request(False, 1.0, ns(middle), "seek-middle")
        assert state == (PAUSED, ns(middle), 1.0, True, "seek-middle")
        client.subscribe("/drake/transforms")  # advertised with the draw it carried (kept: nobody listened)
        assert client.pump(lambda: client.after("seek-middle", "/drake/transforms")), client.seen[-5:]
        log_time, transforms = client.after("seek-middle", "/drake/transforms")[0]
        assert log_time == ns(middle)  # stamped with the timeline's time: paused at that instant
        assert sim_ms(transforms) == drake_lcmtypes.lcmt_viewer_draw.decode(middle.data).timestamp
        # on LCM: the scene again, then that instant's draw, byte for byte
        assert wait_for(lambda: "DRAKE_VIEWER_DRAW" in recorder.messages)
        assert recorder.messages["DRAKE_VIEWER_DRAW"][0] == middle.data
        assert recorder.messages["DRAKE_VIEWER_LOAD_ROBOT"] == [events[0].data] * 2
        assert client.pump(lambda: ns(middle) in client.after("seek-middle", "time")), client.seen[-5:]

        # a speed of 0 is refused, a seek past the end clamped: each said as a status
        refused = client.request(True, 0.0, None, "zero")
        assert refused[0] == PAUSED and refused[1] == ns(middle)
        assert client.pump(lambda: any("refused" in status["message"] for status in client.statuses))

        # play at 2x: the clock runs twice as fast as the wall's
        played_at = time.monotonic()
        status, _, speed, did_seek, _ = client.request(True, 2.0, None, "play-2x")
        assert (status, speed, did_seek) == (PLAYING, 2.0, False)
        # seek back while playing: the first draw's transforms again, then on to the end
        back = draws[len(draws) // 4]
        status, now, speed, did_seek, _ = client.request(True, 2.0, ns(back), "back")
        sought_at = time.monotonic()
        assert (status, speed, did_seek) == (PLAYING, 2.0, True) and 0 <= now - ns(back) < 10**9
        # the world at that instant comes (a draw played just before the seek may come before it)
        back_ms = drake_lcmtypes.lcmt_viewer_draw.decode(back.data).timestamp
        assert client.pump(
            lambda: any(sim_ms(p) == back_ms for _, p in client.after("back", "/drake/transforms"))
        )
        assert client.pump(lambda: any(kind == "state" and state[0] == ENDED for kind, state in client.seen))
        ended_at = time.monotonic()
        assert ended_at - sought_at >= (last - ns(back)) / 1e9 / 2 * 0.9  # never faster than the clock
        ended = next(state for kind, state in client.seen if kind == "state" and state[0] == ENDED)
        assert ended[1] == last
        times = client.after("back", "time")
        assert times[-1] == last and min(times) < ns(middle)  # the clock went back, then to the end
        assert played_at < sought_at
        out = recorder.messages["DRAKE_VIEWER_DRAW"]
        assert out[-1] == draws[-1].data
        # past the end: clamped, said
        assert client.request(False, 1.0, last + 10**9, "past")[1] == last
        assert client.pump(lambda: any("clamped" in status["message"] for status in client.statuses))
    finally:
        if client is not None:
            client.close()
        assert bridge.stop() == 0, bridge.lines
        recorder.close()


def test_an_empty_log_is_one_line_and_exit_2(tmp_path: Path) -> None:
    empty = tmp_path / "empty.lcmlog"
    empty.write_bytes(b"")
    done = subprocess.run([sys.executable, "-m", "viewer_bridge.cli.main", "play", str(empty)],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        f"viewer-bridge play: {empty} holds no whole LCM event: nothing to play"
    ]


def test_a_seek_in_drakes_log_sends_lcm_that_instant_byte_for_byte_and_every_client_the_state(
    drake_log: Path,
) -> None:
    """A log DrakeVisualizer wrote (two roles): after a seek, the first draw of each role an LCM
    subscriber on --lcm-out receives is the log's draw at that instant, after the role's load; a
    second client sees the state that answers the first's request."""
    events = list(read_log(drake_log, "DRAKE_VIEWER_.*"))
    draws = [event for event in events if event.channel == "DRAKE_VIEWER_DRAW_ILLUSTRATION"]
    middle = draws[len(draws) // 2]
    url = lcm_url(3)
    recorder = LcmRecorder(url)
    bridge = PlayProcess(str(drake_log), "-c", "builtin:foxglove", "--paused", "--lcm-out", url)
    clients: list[PlaybackClient] = []
    try:
        port = bridge.port()
        clients = [PlaybackClient(port), PlaybackClient(port)]
        first, second = clients
        assert second.pump(lambda: bool(second.info))
        assert wait_for(lambda: bool(recorder.messages))  # the log's first instant, sent at start
        before = {channel: len(messages) for channel, messages in recorder.messages.items()}
        state = first.request(False, 1.0, ns(middle), "to-the-middle")
        assert state == (PAUSED, ns(middle), 1.0, True, "to-the-middle")
        assert second.pump(lambda: second.answer("to-the-middle") == state), second.seen[-5:]

        def since_seek(channel: str) -> list[bytes]:
            return recorder.messages.get(channel, [])[before.get(channel, 0) :]

        expected = {}
        for event in events:  # the last of each channel at or before the instant
            if event.timestamp_us <= middle.timestamp_us:
                expected[event.channel] = event.data
        assert wait_for(lambda: all(since_seek(channel) for channel in expected)), recorder.messages.keys()
        for channel, data in expected.items():
            assert since_seek(channel)[0] == data, channel  # byte for byte
    finally:
        for client in clients:
            client.close()
        assert bridge.stop() == 0, bridge.lines
        recorder.close()


def test_keys_on_a_terminal_step_draws_change_speed_and_play(demo_log: Path) -> None:
    """`play` on a terminal (a pty): right and left step one draw (LCM gets that draw), + doubles
    the speed, space plays; each key's line says the position; the terminal is restored after."""
    draws = [event.data for event in read_log(demo_log, "DRAKE_VIEWER_DRAW")]
    url = lcm_url(4)
    recorder = LcmRecorder(url)
    leader, follower = os.openpty()
    echo_before = termios.tcgetattr(follower)[3] & termios.ECHO
    command = [sys.executable, "-m", "viewer_bridge.cli.main", "play", str(demo_log), "-c", "builtin:foxglove",
               "--set", "foxglove.port=0", "--paused", "--lcm-out", url]  # fmt: skip
    process = subprocess.Popen(
        command, stdin=follower, stdout=follower, stderr=follower, start_new_session=True
    )
    screen: list[str] = []

    def read() -> None:
        with contextlib.suppress(OSError):  # the pty ends with the process
            while data := os.read(leader, 4096):
                screen.append(data.decode("utf-8", "replace"))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()

    def said(text: str) -> bool:
        return text in "".join(screen)

    def sent() -> list[bytes]:
        return recorder.messages.get("DRAKE_VIEWER_DRAW", [])

    try:
        assert wait_for(lambda: said("keys: space play/pause")), "".join(screen)
        assert wait_for(lambda: termios.tcgetattr(follower)[3] & termios.ECHO == 0)  # cbreak: keys unechoed
        os.write(leader, b"\x1b[C")  # right: the first draw
        assert wait_for(lambda: sent() == draws[:1]), len(sent())
        os.write(leader, b"\x1b[C")
        assert wait_for(lambda: sent() == draws[:2]), len(sent())
        os.write(leader, b"\x1b[D")  # left: back to the first
        assert wait_for(lambda: sent() == [draws[0], draws[1], draws[0]]), len(sent())
        assert wait_for(lambda: said("paused at ")), "".join(screen)
        os.write(leader, b"+")
        assert wait_for(lambda: said(", 2x")), "".join(screen)
        os.write(leader, b" ")  # play: on from the first draw at 2x
        assert wait_for(lambda: said("playing at ")), "".join(screen)
        assert wait_for(lambda: len(sent()) >= 10)
        assert sent()[3:10] == draws[1:8]  # on from the first draw, none skipped
    finally:
        process.send_signal(2)
        code = process.wait(timeout=30)
        reader.join(timeout=5)
        os.close(leader)
        recorder.close()
    assert code == 0, "".join(screen)
    assert termios.tcgetattr(follower)[3] & termios.ECHO == echo_before  # the terminal as it was
    os.close(follower)


def test_indexing_shows_progress_as_other_long_work_does(
    demo_log: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log that takes a while to index says how far it is, in the command line's one way of
    showing long work (here on a pipe: a line per tenth, once the work has run `QUIET_S`)."""
    from viewer_bridge.cli.play import index_log
    from viewer_bridge.util import progress

    monkeypatch.setattr(progress, "QUIET_S", 0.0)  # as if the log were big enough to take seconds
    index = index_log(str(demo_log), "play")
    said = capsys.readouterr().err.splitlines()
    assert len(index) == len(list(read_log(demo_log)))
    assert said and all(line.startswith(f"viewer-bridge play: indexing {demo_log}: ") for line in said), said
    assert "100%" in said[-1] and len(said) <= 11, said  # never a line per event
    assert index_log(str(demo_log), "play", quiet=True) is not None and capsys.readouterr().err == ""
