"""Foxglove's playback bar driving a played timeline (`viewer-bridge play`), through foxglove-sdk.

The server lists the `playbackControl` and `time` capabilities and the timeline's range as its
data range (serverInfo's dataStartTime and dataEndTime). A client's playback control request
(play or pause, a speed, a seek) is applied to the timeline and answered with the playback state,
its request id echoed and `did_seek` set on a seek; every client gets that state, so two clients
that disagree both see the last request win. What a request could not have as asked (a speed
not above 0: refused; a seek outside the range: clamped) is said to the clients as a warning
status. The end of the timeline is broadcast as `ended`, and the clock's time as time messages.
"""

from __future__ import annotations

from typing import Any

from foxglove.websocket import (
    Capability,
    PlaybackCommand,
    PlaybackControlRequest,
    PlaybackState,
    PlaybackStatus,
    StatusLevel,
    WebSocketServer,
)

from viewer_bridge.transports import playback

_STATUS = {
    playback.Status.PLAYING: PlaybackStatus.Playing,
    playback.Status.PAUSED: PlaybackStatus.Paused,
    playback.Status.ENDED: PlaybackStatus.Ended,
}


def sdk_state(state: playback.PlaybackState) -> PlaybackState:
    return PlaybackState(_STATUS[state.status], state.time_ns, state.speed, state.did_seek, state.request_id)


class FoxglovePlayback:
    """A timeline driven by a Foxglove server's clients: `server_options` for `start_server`,
    `attach` once it started, `on_request` from the server's listener."""

    def __init__(self, timeline: playback.Timeline) -> None:
        self.timeline = timeline
        self._server: WebSocketServer | None = None

    def server_options(self, options: dict[str, Any]) -> dict[str, Any]:
        """`start_server`'s `options` with playback: its capabilities added, the time range."""
        capabilities = [*options.get("capabilities", []), Capability.PlaybackControl, Capability.Time]
        return options | {"capabilities": capabilities, "playback_time_range": self.timeline.range_ns}

    def attach(self, server: WebSocketServer) -> None:
        self._server = server
        self.timeline.watch(
            lambda state: server.broadcast_playback_state(sdk_state(state)), server.broadcast_time
        )
        server.broadcast_playback_state(sdk_state(self.timeline.state()))

    def on_request(self, request: PlaybackControlRequest) -> PlaybackState | None:
        answer = self.timeline.request(
            playback.PlaybackRequest(
                play=request.playback_command == PlaybackCommand.Play,
                speed=request.playback_speed,
                seek_ns=request.seek_time,
                request_id=request.request_id,
            )
        )
        server = self._server
        if server is None:  # a request before the server was attached: answered to its client alone
            return sdk_state(answer.state)
        if answer.note is not None:
            server.publish_status(answer.note, StatusLevel.Warning)
        server.broadcast_playback_state(
            sdk_state(answer.state)
        )  # every client: the last request wins for all
        return None
