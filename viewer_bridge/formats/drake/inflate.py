"""A zlib stream inflated into a buffer of the size a header declares, and never past it.

A camera image's header says how many bytes its rows take; a stream that would give more (a zlib
bomb: a few kilobytes that expand to gigabytes) is refused once that buffer is full, before
anything more is allocated. libz's `uncompress2` (through ctypes, as Drake's own reader calls
`uncompress`) writes straight into an uninitialised buffer of exactly that size: one pass, no
copy. Where libz cannot be loaded, Python's `zlib.decompressobj` with a `max_length` does the
same, at the cost of its growing output blocks and a final copy (bench/images.py measures both).

The buffers libz writes into come from a `BufferPool`: a camera sends images of the same sizes
over and over, and a fresh multi-megabyte buffer per image costs a page fault per 4 KiB page
(the allocator hands big blocks back to the kernel when they are freed): on this machine that
was more than the inflating itself. A buffer goes back to the pool once nothing views it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import threading
import weakref
import zlib
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from viewer_bridge.errors import InflateError

Bytes = npt.NDArray[np.uint8]
DEFLATE_MAX_RATIO = 1032  # deflate's best: 258 bytes per 2-bit match code, so no stream gives more
_Z_OK, _Z_MEM_ERROR = 0, -4


class BufferPool:
    """Byte buffers of `smallest` bytes or more, handed out again once nothing views the last one
    handed out; at most `idle` of them are kept while unused. Thread-safe."""

    def __init__(self, smallest: int = 1 << 18, idle: int = 16) -> None:
        self.smallest = smallest
        self.idle = idle
        self._free: dict[int, list[bytearray]] = {}
        self._lock = threading.Lock()

    def take(self, size: int) -> Bytes:
        """`size` bytes (their content: whatever was there) as a writable array."""
        if size < self.smallest:
            return np.empty(size, np.uint8)
        with self._lock:
            free = self._free.get(size)
            owner = free.pop() if free else bytearray(size)
        # Views of this array keep it alive (numpy's views point at the array that wraps the
        # buffer), so the buffer returns only when the last of them is gone.
        rows = np.frombuffer(owner, np.uint8)
        weakref.finalize(rows, self._give, owner)
        return rows

    def _give(self, owner: bytearray) -> None:
        with self._lock:
            if sum(map(len, self._free.values())) < self.idle:
                self._free.setdefault(len(owner), []).append(owner)

    def idle_count(self) -> int:
        with self._lock:
            return sum(map(len, self._free.values()))


def inflate_python(data: bytes | memoryview, size: int) -> Bytes:
    """The stream's bytes (at most `size` of them) by Python's zlib; `InflateError` as `inflate`."""
    inflater = zlib.decompressobj()
    try:
        rows = inflater.decompress(data, size or 1)  # a max_length of 0 would mean no limit
        # Out of room (or cut short): one more byte of room says which, and reads the checksum.
        if len(rows) > size or not inflater.eof and inflater.decompress(inflater.unconsumed_tail, 1):
            raise InflateError(f"zlib data expands past {size} bytes")
    except zlib.error as error:
        raise InflateError(f"not a zlib stream: {error}") from None
    if not inflater.eof:
        raise InflateError(f"zlib stream ends early, after {len(rows)} bytes")
    if inflater.unused_data:
        raise InflateError(f"{len(inflater.unused_data)} bytes after the zlib stream")
    return np.frombuffer(rows, np.uint8)


def _libz_inflater(pool: BufferPool) -> Callable[[bytes | memoryview, int], Bytes] | None:
    """`inflate` by libz's uncompress2 (zlib 1.2.9 and later), or None where it cannot be loaded."""
    name = ctypes.util.find_library("z")
    try:
        uncompress2 = ctypes.CDLL(name or "libz.so.1").uncompress2
    except (OSError, AttributeError):
        return None
    size_t = ctypes.c_ulong  # zlib's uLong
    uncompress2.argtypes = (ctypes.c_void_p, ctypes.POINTER(size_t), ctypes.c_void_p, ctypes.POINTER(size_t))
    uncompress2.restype = ctypes.c_int

    def inflate_libz(data: bytes | memoryview, size: int) -> Bytes:
        """The stream's bytes, at most `size` of them, by libz; `InflateError` as `inflate`."""
        # No room (libz takes it as a room of one byte it does not report), or more room than the
        # stream could fill (a header declaring gigabytes): Python's zlib, whose output grows only
        # as the stream gives it, says what is wrong without the room being allocated.
        source = np.frombuffer(data, np.uint8)
        if not size or size > DEFLATE_MAX_RATIO * len(source) + 64:
            return inflate_python(data, size)
        rows = pool.take(size)
        written, read = size_t(size), size_t(len(source))
        status = uncompress2(rows.ctypes.data, ctypes.byref(written), source.ctypes.data, ctypes.byref(read))
        if status == _Z_MEM_ERROR:
            raise MemoryError("libz could not allocate its inflate state")
        if status != _Z_OK:  # libz's status says less than why: Python's zlib names it (refusals only)
            inflate_python(data, size)
            raise InflateError(f"not a whole zlib stream (libz status {status})")
        if read.value != len(source):
            raise InflateError(f"{len(source) - read.value} bytes after the zlib stream")
        return rows[: written.value]

    return inflate_libz


POOL = BufferPool()
inflate_libz = _libz_inflater(POOL)
# The zlib stream `data` inflated: at most `size` bytes (fewer when the stream is shorter), or
# `InflateError` for a stream that would give more, is corrupt, ends early or has bytes after it.
inflate: Callable[[bytes | memoryview, int], Bytes] = inflate_libz or inflate_python
