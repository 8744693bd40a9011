"""What the rerun transport and the Rerun translators agree on: the message and how its bytes are laid out.

Rerun's data are chunks: Arrow record batches carrying Rerun's metadata (entity path, archetype
and component of each column, which columns are timelines). A message of type `rerun.Chunks`
is one or more of them, each an Arrow IPC stream prefixed by its length (4 bytes, little-endian):
the translators build the batches, the transport hands them to the SDK's recording stream
(`Chunk.from_record_batch`, `send_chunks`) and knows nothing of scenes.

Two timelines, named here once: `sim_time` (Drake's simulation time, a duration) and
`receive_time` (when the bridge received the message, a timestamp).

pyarrow (the rerun extra's) is imported by the two functions that use it, not at load: every
translator module reads the names below through `translators/types.py`, and a route to Foxglove
or Zenoh must not need the rerun extra.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from typing import TYPE_CHECKING

from viewer_bridge.errors import DecodeError

if TYPE_CHECKING:
    import pyarrow as pa

RERUN = "rerun"  # the encoding: Arrow IPC streams of Rerun chunks
CHUNKS = "rerun.Chunks"
SIM_TIME = "sim_time"
RECEIVE_TIME = "receive_time"

_LENGTH = struct.Struct("<I")

__all__ = ["CHUNKS", "RECEIVE_TIME", "RERUN", "SIM_TIME", "decode_batches", "encode_batches"]


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


def decode_batches(data: bytes) -> list[pa.RecordBatch]:
    """The record batches of a message; `DecodeError` naming the offset of a bad one."""
    import pyarrow as pa
    batches, offset = [], 0
    view = memoryview(data)
    while offset < len(data):
        if offset + _LENGTH.size > len(data):
            raise DecodeError(CHUNKS, "length", offset, "truncated length prefix")
        (size,) = _LENGTH.unpack_from(data, offset)
        start, offset = offset + _LENGTH.size, offset + _LENGTH.size + size
        if offset > len(data):
            raise DecodeError(CHUNKS, "stream", start, f"{size} bytes announced, {len(data) - start} left")
        try:
            batches.extend(pa.ipc.open_stream(pa.py_buffer(view[start:offset])))
        except pa.ArrowInvalid as error:
            raise DecodeError(CHUNKS, "stream", start, str(error)) from error
    return batches
