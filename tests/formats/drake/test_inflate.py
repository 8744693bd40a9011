"""Inflating into the declared size: libz's path and Python's agree, and neither goes past it."""

from __future__ import annotations

import tracemalloc
import zlib
from collections.abc import Callable

import numpy as np
import pytest

from viewer_bridge.errors import InflateError
from viewer_bridge.formats.drake.inflate import Bytes, inflate, inflate_libz, inflate_python

ROWS = bytes(range(256)) * 40
INFLATERS: list[Callable[[bytes | memoryview, int], Bytes]] = [inflate_python]
if inflate_libz is not None:
    INFLATERS.append(inflate_libz)


def test_libz_is_the_one_used_here() -> None:
    assert inflate_libz is not None and inflate is inflate_libz


@pytest.mark.parametrize("inflater", INFLATERS, ids=lambda f: f.__name__)
def test_a_stream_inflates_to_its_bytes_whatever_the_room(
    inflater: Callable[[bytes | memoryview, int], Bytes],
) -> None:
    stream = zlib.compress(ROWS, 1)
    assert inflater(stream, len(ROWS)).tobytes() == ROWS
    assert (
        inflater(memoryview(b"xx" + stream)[2:], len(ROWS) + 10).tobytes() == ROWS
    )  # fewer: the caller checks
    assert inflater(zlib.compress(b""), 0).tobytes() == b""


CASES = {
    "longer than the room": (zlib.compress(ROWS), len(ROWS) - 1, "zlib data expands past 10239 bytes"),
    "no room at all": (zlib.compress(b"x"), 0, "zlib data expands past 0 bytes"),
    "cut in its checksum": (zlib.compress(ROWS)[:-2], len(ROWS), "ends early"),
    "cut in its data": (zlib.compress(ROWS)[:20], len(ROWS), "ends early"),
    "not zlib": (b"\x00\x01 nothing", 100, "not a zlib stream"),
    "empty": (b"", 100, "ends early"),
    "bytes after it": (zlib.compress(ROWS) + b"abc", len(ROWS), "3 bytes after the zlib stream"),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("inflater", INFLATERS, ids=lambda f: f.__name__)
def test_both_refuse_alike(inflater: Callable[[bytes | memoryview, int], Bytes], case: str) -> None:
    data, size, reason = CASES[case]
    with pytest.raises(InflateError, match=reason):
        inflater(data, size)


@pytest.mark.parametrize("inflater", INFLATERS, ids=lambda f: f.__name__)
def test_a_bomb_is_refused_within_the_room(inflater: Callable[[bytes | memoryview, int], Bytes]) -> None:
    bomb = zlib.compress(bytes(256 << 20), 9)  # 256 MiB of zeros in 255 KiB
    tracemalloc.start()
    try:
        with pytest.raises(InflateError, match="expands past 4096 bytes"):
            inflater(bomb, 4096)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20
    assert np.array_equal(inflater(zlib.compress(bytes(4096)), 4096), np.zeros(4096, np.uint8))


def test_a_pooled_buffer_is_handed_out_again_only_once_no_view_of_it_is_left() -> None:
    import gc

    from viewer_bridge.formats.drake.inflate import BufferPool

    pool = BufferPool(smallest=1000, idle=2)
    first = pool.take(4096)
    view = first[10:20].reshape(2, 5)  # what an image's pixels are: a view
    address = first.ctypes.data
    del first
    gc.collect()
    assert pool.idle_count() == 0  # the view still holds it
    second = pool.take(4096)
    assert second.ctypes.data != address
    del view
    gc.collect()
    assert pool.idle_count() == 1
    again = pool.take(4096)
    assert again.ctypes.data == address and pool.idle_count() == 0
    assert pool.take(10).base is None  # small ones are not pooled
    held = [pool.take(2000) for _ in range(3)]
    del held, again, second
    gc.collect()
    assert pool.idle_count() == 2  # no more than `idle` kept


@pytest.mark.parametrize("inflater", INFLATERS, ids=lambda f: f.__name__)
def test_a_room_no_stream_could_fill_is_never_allocated(
    inflater: Callable[[bytes | memoryview, int], Bytes],
) -> None:
    """bench/fuzz.py's finding (drake_images, drake_images_to_ros): libz's room was allocated at
    the declared size, so a header declaring 4 GiB over a few bytes of stream ran out of memory."""
    tracemalloc.start()
    try:
        rows = inflater(zlib.compress(b"tiny"), 1 << 32)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert rows.tobytes() == b"tiny" and peak < 1 << 20
