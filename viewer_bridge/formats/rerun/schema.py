"""What the rerun transport and the Rerun translators agree on: the message, as an object and as bytes.

Rerun's data are chunks: columns of Arrow data with Rerun's metadata (entity path, archetype and
component of each column, which columns are timelines). A message of type `rerun.Chunks` is one
or more of them. Within the bridge's process it crosses the router as a `Chunks` value, the
SDK's own chunks (`rerun.chunk.Chunk`), which the transport hands to the SDK's `send_chunks` as
they are: the translators build them, the transport knows nothing of scenes. As bytes (for a
publisher that takes only bytes, and `Chunks.decode`), each chunk is its Arrow record batch as an
Arrow IPC stream prefixed by its length (4 bytes, little-endian).

Two timelines, named here once: `sim_time` (Drake's simulation time, a duration) and
`receive_time` (when the bridge received the message, a timestamp).

pyarrow and the SDK (the rerun extra's) are imported by the functions that use them, not at load:
every translator module reads the names below through `translators/types.py`, and a route to
Foxglove or Zenoh must not need the rerun extra.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Self

from viewer_bridge.errors import DecodeError
from viewer_bridge.payload import Value

if TYPE_CHECKING:
    import pyarrow as pa
    from rerun.chunk import Chunk

RERUN = "rerun"  # the encoding: Rerun chunks (`Chunks`)
CHUNKS = "rerun.Chunks"
SIM_TIME = "sim_time"
RECEIVE_TIME = "receive_time"

_LENGTH = struct.Struct("<I")


class Chunks(Value):
    """One `rerun.Chunks` message: the SDK's chunks, and how many bytes of component data their
    builder put in them (`size`; the SDK tells a chunk's size only by copying it out)."""

    __slots__ = ("chunks", "_size")

    def __init__(self, chunks: Sequence[Chunk], size: int) -> None:
        self.chunks = chunks
        self._size = size

    @property
    def size(self) -> int:
        return self._size

    @classmethod
    def joined(cls, parts: Iterable[Chunks]) -> Chunks:
        """One message of every part's chunks, in order."""
        parts = list(parts)
        return cls([chunk for part in parts for chunk in part.chunks], sum(part.size for part in parts))

    def encode(self) -> bytes:
        return encode_batches(chunk.to_record_batch() for chunk in self.chunks)

    @classmethod
    def decode(cls, data: bytes) -> Self:
        """The chunks of a message's bytes; `DecodeError` for a bad stream or a batch that is no chunk."""
        from rerun.chunk import Chunk

        chunks: list[Chunk] = []
        size = 0
        for offset, batch in decode_batches(data):
            try:
                chunks += Chunk.from_record_batch(batch)
            except ValueError as error:  # no Rerun metadata, columns of unequal length, ...
                raise DecodeError(CHUNKS, "chunk", offset, str(error)) from error
            size += batch.nbytes
        return cls(chunks, size)


def encode_batches(batches: Iterable[pa.RecordBatch]) -> bytes:
    """Record batches (each with a schema of its own) as one message's bytes."""
    import pyarrow as pa

    parts: list[bytes] = []
    for batch in batches:
        sink = pa.BufferOutputStream()
        with pa.ipc.new_stream(sink, batch.schema) as writer:
            writer.write_batch(batch)
        stream = sink.getvalue()
        parts += (_LENGTH.pack(stream.size), stream.to_pybytes())
    return b"".join(parts)


def decode_batches(data: bytes) -> list[tuple[int, pa.RecordBatch]]:
    """The record batches of a message, each with its stream's offset; `DecodeError` naming the
    offset of a bad one."""
    import pyarrow as pa

    batches: list[tuple[int, pa.RecordBatch]] = []
    offset = 0
    view = memoryview(data)
    while offset < len(data):
        if offset + _LENGTH.size > len(data):
            raise DecodeError(CHUNKS, "length", offset, "truncated length prefix")
        (size,) = _LENGTH.unpack_from(data, offset)
        start, offset = offset + _LENGTH.size, offset + _LENGTH.size + size
        if offset > len(data):
            raise DecodeError(CHUNKS, "stream", start, f"{size} bytes announced, {len(data) - start} left")
        try:
            batches.extend((start, batch) for batch in pa.ipc.open_stream(pa.py_buffer(view[start:offset])))
        except pa.ArrowInvalid as error:
            raise DecodeError(CHUNKS, "stream", start, str(error)) from error
    return batches
