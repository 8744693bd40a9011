"""What a route counts: messages and bytes in and out, errors and warnings by kind, and the
translate time and latency of its recent messages (as percentiles in a snapshot)."""

from __future__ import annotations

import json
import logging
import threading
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer_bridge.router.flow import Mailbox
from viewer_bridge.router.status import Percentiles, RouteSnapshot, Snapshot, StatusView

_SAMPLES = 4096  # latency and translate-time samples kept per route (a ring)


@dataclass
class RouteStats:
    messages_in: int = 0
    messages_out: int = 0
    bytes_in: int = 0
    bytes_out: int = 0
    idle_skipped: int = 0  # messages a lazy route did not translate: nobody was listening
    # Peers whose QoS cannot match one of the route's subscriptions or publishers (events, not messages).
    qos_incompatible: int = 0
    streams_reclaimed: int = 0  # streams quiet for `stream_idle_s` whose lanes went to new ones
    errors: Counter[str] = field(default_factory=Counter)
    # e.g. a geometry skipped (viewer_bridge.model.skipped)
    warnings: Counter[str] = field(default_factory=Counter)
    # Messages held back on purpose, by channel and kind (unknown_type, refused_type, waiting_for_build,
    # own_message: the bridge's own message come back, `viewer_bridge.router.echoes`).
    held: dict[str, Counter[str]] = field(default_factory=dict)
    translate_ms: deque[float] = field(default_factory=lambda: deque(maxlen=_SAMPLES))
    latency_ms: deque[float] = field(default_factory=lambda: deque(maxlen=_SAMPLES))

    def snapshot(self, mailbox: Mailbox, state: str, unsent: int) -> RouteSnapshot:
        """The counters as `--stats-json` writes them; `dropped` is the sum of `superseded` and
        `mailbox_full` (what it said before they were apart); `unsent` is the transport's count."""
        return {
            "state": state,
            "messages_in": self.messages_in,
            "messages_out": self.messages_out,
            "bytes_in": self.bytes_in,
            "bytes_out": self.bytes_out,
            "idle_skipped": self.idle_skipped,
            "qos_incompatible": self.qos_incompatible,
            "streams_reclaimed": self.streams_reclaimed,
            "errors": dict(self.errors),
            "warnings": dict(self.warnings),
            "held": {channel: dict(kinds) for channel, kinds in sorted(self.held.items())},
            "superseded": mailbox.superseded,
            "mailbox_full": mailbox.mailbox_full,
            "dropped": mailbox.dropped,
            "max_hz_skipped": mailbox.rate_skipped,  # superseded while a rate-limited route waited
            "queued": len(mailbox),
            "translate_ms": _percentiles(self.translate_ms),
            "latency_ms": _percentiles(self.latency_ms),
            "unsent": unsent,
        }


def _percentiles(samples: deque[float]) -> Percentiles:
    if not samples:
        return {"p50": None, "p99": None, "max": None}
    values = np.fromiter(samples, dtype=np.float64)
    p50, p99 = np.percentile(values, [50, 99])
    return {"p50": round(float(p50), 4), "p99": round(float(p99), 4), "max": round(float(values.max()), 4)}


_log = logging.getLogger(__name__)
_skipped = threading.Event()  # a report was skipped (said once)


def report_safely(snapshot: Callable[[], Snapshot], view: StatusView, stats_json: Path | None) -> None:
    """`report` of what `snapshot` makes; one that fails for want of a file (EMFILE: the process
    is out of them), a full disk or the like is skipped, said once: the stats never stop the bridge."""
    try:
        report(snapshot(), view, stats_json)
    except OSError as error:
        if not _skipped.is_set():
            _skipped.set()
            _log.warning("a stats report was skipped (%s); the next is tried at its time (said once)", error)


def report(snapshot: Snapshot, view: StatusView, stats_json: Path | None) -> None:
    """A snapshot to the status view, and to the JSON file when asked for (replaced whole, so a
    reader never sees half of it)."""
    view.show(snapshot)
    if stats_json is not None:
        temporary = stats_json.with_suffix(".tmp")
        temporary.write_text(json.dumps(snapshot, indent=2))
        temporary.replace(stats_json)
