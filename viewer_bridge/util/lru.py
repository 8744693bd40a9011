"""A least-recently-used map bounded by the total size of its values, not by their count.

The render path keeps two such caches: decoded base64 payloads (`formats.gltf`) and mesh buffers
on the GPU (`render.MeshCache`). Sizes are the caller's (bytes, usually); what is evicted is
handed back, so a caller that owns resources (GPU buffers) can release them. Not thread-safe:
a caller shared between threads holds its own lock around each call.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Hashable
from typing import Generic, TypeVar

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")


class SizedLru(Generic[K, V]):
    """Entries by key, the least recently used evicted once their sizes add up to more than
    `max_size`. With `keep_newest`, the entry just put stays even when it alone is larger."""

    def __init__(self, max_size: int, keep_newest: bool = False) -> None:
        self.max_size = max_size
        self.keep_newest = keep_newest
        self.total = 0  # the sizes of the entries held
        self._entries: OrderedDict[K, tuple[V, int]] = OrderedDict()

    def get(self, key: K) -> V | None:
        """The value, now the most recently used; None when it is not held."""
        entry = self._entries.get(key)
        if entry is None:
            return None
        self._entries.move_to_end(key)
        return entry[0]

    def put(self, key: K, value: V, size: int) -> list[V]:
        """Holds `value` (unless `key` is held already), then evicts down to `max_size`; returns
        what was evicted, oldest first."""
        if key not in self._entries:
            self._entries[key] = (value, size)
            self.total += size
        evicted = []
        floor = 1 if self.keep_newest else 0
        while self.total > self.max_size and len(self._entries) > floor:
            _, (old, old_size) = self._entries.popitem(last=False)
            self.total -= old_size
            evicted.append(old)
        return evicted

    def __contains__(self, key: object) -> bool:
        return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def keys(self) -> list[K]:
        """The keys held, least recently used first."""
        return list(self._entries)

    def values(self) -> list[V]:
        """The values held, least recently used first."""
        return [value for value, _ in self._entries.values()]
