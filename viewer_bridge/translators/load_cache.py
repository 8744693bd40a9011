"""The last Drake load seen per load channel, shared by the routes of a router (and, with a folder, runs).

A module of its own because the router makes it (with the config's `load_cache` folder) and gives it
to its translators through `Shared`, while reading the loads it holds is `drake_stream`'s business.
"""

from __future__ import annotations

import os
import re
import tempfile
import threading
from pathlib import Path


class LoadCache:
    """The last `lcmt_viewer_load_robot` bytes seen per load channel, shared by every route.

    With a folder, loads are also written there (one file per channel) and read back at start,
    so a bridge restarted while the simulation runs still has the model: Drake sends a load
    only when the geometry changes.
    """

    def __init__(self, folder: str | Path | None = None) -> None:
        self._loads: dict[str, bytes] = {}
        self._lock = threading.Lock()
        self._folder = Path(folder).expanduser() if folder else None
        if self._folder is not None and self._folder.is_dir():
            for path in self._folder.glob("*.lcm"):
                self._loads[path.stem] = path.read_bytes()

    def put(self, channel: str, data: bytes) -> None:
        # Under the lock, file and memory change together: routes putting the same channel's
        # loads cannot leave an older one on disk than in memory.
        with self._lock:
            if self._loads.get(channel) == data:
                return
            self._loads[channel] = data
            if self._folder is not None and re.fullmatch(r"[A-Za-z0-9_.<>-]+", channel):
                self._folder.mkdir(parents=True, exist_ok=True)
                with tempfile.NamedTemporaryFile(dir=self._folder, delete=False) as file:
                    file.write(data)
                os.replace(file.name, self._folder / f"{channel}.lcm")

    def get(self, channel: str) -> bytes | None:
        with self._lock:
            return self._loads.get(channel)
