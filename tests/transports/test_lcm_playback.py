"""The log index and the player of `viewer-bridge play`, in this process: events indexed as LCM's
own reader reads them, a damaged or disordered log tolerated (said once), the world at a seek's
instant re-sent, requests refused or clamped with a note, the end reached."""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import pytest

from tests.peers import wait_for
from viewer_bridge.errors import LogError
from viewer_bridge.transports.lcm import LcmEvent, read_log, write_log
from viewer_bridge.transports.lcm_log_index import LogIndex
from viewer_bridge.transports.lcm_playback import LogPlayer
from viewer_bridge.transports.playback import PlaybackRequest, PlaybackState, Status

T0 = 1_700_000_000_000_000  # a log's first time, microseconds


def events() -> list[LcmEvent]:
    """A load, then draws every 10 ms for a second, a status channel every 100 ms, a second load at 0.5 s."""
    made = [LcmEvent("LOAD", b"load-1", T0)]
    for step in range(101):
        made.append(LcmEvent("DRAW", b"draw-%d" % step, T0 + step * 10_000))
        if step % 10 == 5:
            made.append(LcmEvent("STATUS", b"status-%d" % step, T0 + step * 10_000 + 1))
        if step == 50:
            made.append(LcmEvent("LOAD", b"load-2", T0 + step * 10_000 + 2))
    return made


@pytest.fixture
def log_path(tmp_path: Path) -> Path:
    path = tmp_path / "x.lcmlog"
    write_log(path, events())
    return path


def test_the_index_holds_every_event_lcm_reads(log_path: Path) -> None:
    index = LogIndex.build(log_path)
    try:
        played = [(e.channel, e.data, e.utime) for e in index.events()]
        assert played == [(e.channel, e.data, e.timestamp_us) for e in read_log(log_path)]
        assert (index.first_us, index.last_us) == (T0, T0 + 1_000_000)
        assert sorted(index.channels) == ["DRAW", "LOAD", "STATUS"]
    finally:
        index.close()


def test_the_world_at_an_instant_is_the_last_event_of_each_channel(log_path: Path) -> None:
    index = LogIndex.build(log_path)
    try:
        at = [index.event(p) for p in index.latched(index.position(T0 + 523_000))]
        assert {e.channel: e.data for e in at} == {
            "LOAD": b"load-2",
            "DRAW": b"draw-52",
            "STATUS": b"status-45",
        }
        assert [e.utime for e in at] == sorted(e.utime for e in at)  # in time order
        before_second_load = [index.event(p).data for p in index.latched(index.position(T0 + 500_000))]
        assert b"load-1" in before_second_load and b"draw-50" in before_second_load
        assert [index.event(p).data for p in index.latched(0)] == []
    finally:
        index.close()


def test_a_partial_last_event_and_garbage_are_skipped_and_said(
    log_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    whole = log_path.read_bytes()
    damaged = log_path.with_name("damaged.lcmlog")
    # garbage between two events (after the first one's 28 + 4 + 6 bytes), and a cut last event
    damaged.write_bytes(whole[:38] + b"\x00garbage\x00" + whole[38:-3])
    with caplog.at_level(logging.WARNING):
        index = LogIndex.build(damaged)
    try:
        assert len(index) == len(events()) - 1
        assert index.event(1).data == b"draw-0"
        said = caplog.text
        assert "9 bytes that are no LCM event were skipped" in said
        assert "ends in a partial event" in said
    finally:
        index.close()


def test_events_out_of_time_order_are_played_in_time_order(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "merged.lcmlog"
    write_log(path, [LcmEvent("A", b"2", T0 + 2), LcmEvent("B", b"1", T0 + 1), LcmEvent("A", b"3", T0 + 3)])
    with caplog.at_level(logging.WARNING):
        index = LogIndex.build(path)
    try:
        assert [e.data for e in index.events()] == [b"1", b"2", b"3"]
        assert caplog.text.count("earlier than the event before them") == 1
    finally:
        index.close()


def test_not_a_log_is_refused_and_an_empty_one_has_no_events(tmp_path: Path) -> None:
    (tmp_path / "text").write_text("hello, world")
    with pytest.raises(LogError, match="not an LCM log"):
        LogIndex.build(tmp_path / "text")
    (tmp_path / "empty").write_bytes(b"")
    assert len(LogIndex.build(tmp_path / "empty")) == 0


class Played:
    """What a player delivered, and the states and times it told."""

    def __init__(self, player: LogPlayer) -> None:
        self.events: list[tuple[str, bytes, int]] = []
        self.states: list[PlaybackState] = []
        self.times: list[int] = []
        self._lock = threading.Lock()
        player.subscribe(".*", self._event)
        player.watch(self.states.append, self.times.append)

    def _event(self, channel: str, data: bytes, utime: int) -> None:
        with self._lock:
            self.events.append((channel, data, utime))

    def data(self) -> list[bytes]:
        with self._lock:
            return [data for _, data, _ in self.events]


def test_a_paused_seek_sends_the_world_at_that_instant_and_playing_reaches_the_end(log_path: Path) -> None:
    index = LogIndex.build(log_path)
    published: list[tuple[str, bytes]] = []

    class Out:
        def publish(self, channel: str, data: bytes) -> None:
            published.append((channel, data))

    player = LogPlayer(index, paused=True, out=Out())
    played = Played(player)
    player.start()
    try:
        assert wait_for(lambda: played.data() == [b"load-1", b"draw-0"])
        answer = player.request(
            PlaybackRequest(play=False, speed=1.0, seek_ns=(T0 + 523_000) * 1000, request_id="a")
        )
        assert answer.note is None
        assert answer.state == PlaybackState(Status.PAUSED, (T0 + 523_000) * 1000, 1.0, True, "a")
        assert wait_for(lambda: len(played.data()) == 5)
        assert played.data()[2:] == [b"status-45", b"load-2", b"draw-52"]
        assert played.times[-1] == (T0 + 523_000) * 1000
        refused = player.request(PlaybackRequest(play=True, speed=0.0, request_id="b"))
        assert refused.note is not None and "refused" in refused.note
        assert refused.state.status == Status.PAUSED and refused.state.request_id == "b"
        clamped = player.request(PlaybackRequest(play=False, speed=1.0, seek_ns=(T0 + 900_000) * 1000))
        assert clamped.note is None
        late = player.request(
            PlaybackRequest(play=True, speed=4.0, seek_ns=(T0 + 5_000_000) * 1000, request_id="c")
        )
        assert late.note is not None and "clamped" in late.note
        assert late.state.time_ns == (T0 + 1_000_000) * 1000
        assert wait_for(lambda: any(state.status == Status.ENDED for state in played.states))
        assert played.data()[-1] == b"draw-100"
        assert not player.finished.is_set()  # a watcher may seek back
        assert published == [(channel, data) for channel, data, _ in played.events]
    finally:
        player.close()


def test_a_log_played_at_speed_ends_in_time_order(log_path: Path) -> None:
    player = LogPlayer(LogIndex.build(log_path), speed=10.0)
    delivered: list[bytes] = []
    player.subscribe(".*", lambda channel, data, received_us: delivered.append(data))
    player.start()
    try:
        assert player.finished.wait(60)  # nobody watches: finished at the end
        assert delivered == [event.data for event in events()]
    finally:
        player.close()


def test_a_looped_log_plays_from_its_start_again(log_path: Path) -> None:
    player = LogPlayer(LogIndex.build(log_path), speed=20.0, loop=True)
    delivered: list[bytes] = []
    player.subscribe(".*", lambda channel, data, received_us: delivered.append(data))
    player.start()
    try:
        # once through, then the world at the first instant (the first load and draw) and on
        assert wait_for(lambda: len(delivered) > len(events()) + 10)
        once = [event.data for event in events()]
        assert delivered[: len(once)] == once
        assert delivered[len(once) : len(once) + 3] == [b"load-1", b"draw-0", b"draw-1"]
        assert not player.finished.is_set()
    finally:
        player.close()


def test_a_step_pauses_at_the_next_or_previous_draw(log_path: Path) -> None:
    player = LogPlayer(LogIndex.build(log_path), paused=True)
    states: list[PlaybackState] = []
    player.watch(states.append, lambda now_ns: None)
    try:
        forward = player.step(1, "DRAW")
        assert forward.state.time_ns == (T0 + 10_000) * 1000  # draw-0 is at the first instant: draw-1
        assert player.step(2, "DRAW").state.time_ns == (T0 + 30_000) * 1000
        assert player.step(-1, "DRAW").state.time_ns == (T0 + 20_000) * 1000
        assert player.step(-100, "DRAW").state.time_ns == T0 * 1000  # no further back than the first
        assert all(state.status == Status.PAUSED and state.did_seek for state in states) and len(states) == 4
        assert player.step(1, "NOTHING").note == "no channel matches 'NOTHING': nothing to step to"
    finally:
        player.close()
