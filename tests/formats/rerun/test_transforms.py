"""A draw as one Rerun chunk, built from the arrays, against the SDK's own column builder
(tests/formats/rerun/oracle.py): as the chunk the transport is handed, and through its bytes."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from rerun.chunk import Chunk

from tests.formats.rerun.oracle import transforms_batch
from viewer_bridge.formats.rerun.chunks import Stamp
from viewer_bridge.formats.rerun.schema import Chunks
from viewer_bridge.formats.rerun.transforms import TransformsEncoder
from viewer_bridge.model.scene import frame_name

sys.path.insert(0, str(Path(__file__).parents[3] / "bench"))
from common import frame  # noqa: E402


def _columns(chunk: Chunk) -> dict[str, object]:
    """The chunk's data (ids left out: each build makes its own)."""
    table = chunk.to_record_batch()
    return {
        name: table.column(name).to_pylist() for name in table.schema.names if name != "rerun.controls.RowId"
    }


@pytest.mark.parametrize("links", [1, 7, 1000])
def test_encoder_equals_the_sdks_columns(links: int) -> None:
    poses, stamp = frame(links, seed=links), Stamp(1_234_000_000, 1_700_000_000_000_000_000)
    encoder = TransformsEncoder("/drake/transforms", frame_name, "tf#/")
    ours = encoder.encode(poses, stamp)
    (expected_chunk,) = Chunk.from_record_batch(
        transforms_batch("/drake/transforms", poses, frame_name, "tf#/", stamp)
    )
    expected = _columns(expected_chunk)
    (as_bytes,) = Chunks.decode(ours.encode()).chunks
    for chunk in (*ours.chunks, as_bytes):
        got = _columns(chunk)
        assert chunk.entity_path == "/drake/transforms"
        assert got.keys() == expected.keys()
        for name, values in expected.items():  # float32 in both: the same values exactly
            assert got[name] == values, name
    assert ours.size >= links * (3 + 4) * 4  # the floats at least


def test_new_link_names_new_frames() -> None:
    encoder = TransformsEncoder("/t", frame_name, "world")
    encoder.encode(frame(3), Stamp(0, 0))
    (chunk,) = encoder.encode(frame(5), Stamp(0, 0)).chunks
    assert chunk.to_record_batch().column("Transform3D:child_frame").to_pylist() == [
        [frame_name(n)] for n in frame(5).names
    ]
