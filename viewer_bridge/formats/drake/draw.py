"""Drake's `lcmt_viewer_draw` (every link's pose) to and from `LinkPoses`.

`poses_from_draw` reads a decoded message; the fast paths, `DrawDecoder` (numpy views into one
copy of the buffer) and `DrawEncoder` (bytes written from the arrays), skip the generic codec
for every frame and keep its errors and bytes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from viewer_bridge.errors import EncodeError
from viewer_bridge.lcmcodec.codecs import DRAW
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.lcmcodec.serde import LcmMessage
from viewer_bridge.model.scene import LinkPoses


def poses_from_draw(message: LcmMessage) -> LinkPoses:
    """A decoded `lcmt_viewer_draw` as arrays (copies, native float64)."""
    count = message.num_links
    return LinkPoses(
        timestamp_ms=message.timestamp,
        names=tuple(message.link_name),
        robot_nums=np.asarray(message.robot_num, dtype=np.int32).reshape(count),
        positions=np.asarray(message.position, dtype=np.float64).reshape(count, 3),
        quaternions_wxyz=np.asarray(message.quaternion, dtype=np.float64).reshape(count, 4),
    )


_HEADER = struct.Struct(">qi")
_BIG_F32, _BIG_I32 = np.dtype(">f4"), np.dtype(">i4")
_TIMESTAMP = struct.Struct(">q")
_U32 = struct.Struct(">I")
_NAMES_AT = 20  # fingerprint (8), timestamp (8), num_links (4)


@dataclass(frozen=True, slots=True)
class _DrawLayout:
    """What a draw's names and robot numbers imply: the names, and where the floats sit.

    `key` is the draw's bytes from `num_links` to the end of the robot numbers; a draw that
    has the same bytes there (compared in place) and is `size` bytes long has these names and
    robot numbers (the robot numbers are a view of the key), and its floats at `floats_at`.
    """

    key: bytes
    names: tuple[str, ...]
    robot_nums: npt.NDArray[np.int32]
    size: int
    floats_at: int  # position (N x 3), then quaternion (N x 4), float32, to the end

    @classmethod
    def after_names(cls, data: bytes, names_end: int, names: tuple[str, ...]) -> _DrawLayout | None:
        """The layout, or None when `data` is not as long as these names make a draw."""
        count = len(names)
        floats_at = names_end + 4 * count  # after an int32 robot_num per link
        if len(data) != floats_at + 28 * count:
            return None
        key = bytes(data[_NAMES_AT - 4 : floats_at])
        robot_nums = np.frombuffer(key, _BIG_I32, count, len(key) - 4 * count)
        return cls(key, names, robot_nums, len(data), floats_at)


_FINGERPRINT = DRAW.packed_fingerprint
_NO_LAYOUT = _DrawLayout(b"", (), np.zeros(0, dtype=np.int32), -1, 0)


class DrawDecoder:
    """Fast `lcmt_viewer_draw` decoding into numpy arrays.

    The link names and robot numbers rarely change between frames, so what they imply is kept
    and reused while the next frame has the same bytes there: a memory comparison and a length
    check instead of N string decodes. The positions and quaternions come back as native
    float32 arrays (views of one copy of the draw's floats, checked finite), the robot numbers
    as a read-only big-endian int32 array. One decoded draw may feed several routes: never
    change the arrays. Anything irregular is handed to the generic decoder, so the same inputs
    raise the same `DecodeError`s as `DRAW.strict.decode`.
    """

    def __init__(self) -> None:
        # One object holding names, robot numbers and offsets: replaced in one store, so routes
        # sharing a decoder on several threads never see one draw's names with another's offsets.
        self._layout = _NO_LAYOUT

    def decode(self, data: Buffer) -> LinkPoses:
        """The poses of one `lcmt_viewer_draw`, as arrays (read-only: never change them).

        Raises:
            DecodeError: bytes that are no `lcmt_viewer_draw`, naming the field and offset.
        """
        if not isinstance(data, bytes):
            data = bytes(data)  # bytes compare in place; a view of a copy stays valid
        known = self._layout
        layout = (
            known
            if len(data) == known.size
            and data.startswith(_FINGERPRINT)
            and data.startswith(known.key, _NAMES_AT - 4)
            else self._new_layout(data)
        )
        if layout is None:
            return self._generic(data)
        # One copy of the floats, native and from an aligned copy of the bytes (numpy swaps
        # unaligned data at a third of the speed): checked here, and what every consumer gets,
        # since aligned native arrays are what numpy computes with fastest.
        floats: np.ndarray[Any, Any] = np.frombuffer(data[layout.floats_at :], _BIG_F32).astype(np.float32)
        count = len(layout.names)
        if 0 in np.isfinite(floats).tobytes():  # a False; faster than numpy's own counting
            return self._generic(data)  # which names the field and offset
        return LinkPoses.of_arrays(
            _TIMESTAMP.unpack_from(data, 8)[0],
            layout.names,
            layout.robot_nums,
            floats[: 3 * count].reshape(count, 3),
            floats[3 * count :].reshape(count, 4),
        )

    @staticmethod
    def _generic(data: Buffer) -> LinkPoses:
        return poses_from_draw(DRAW.strict.decode(data))

    def _new_layout(self, data: bytes) -> _DrawLayout | None:
        """Parse the name block and keep its layout; None when the draw is not well formed."""
        if len(data) < _NAMES_AT or not data.startswith(_FINGERPRINT):
            return None
        _, count = _HEADER.unpack_from(data, 8)
        parsed = _parse_names(data, count)
        if parsed is None:
            return None
        layout = _DrawLayout.after_names(data, *parsed)
        if layout is not None:
            self._layout = layout
        return layout


def _parse_names(data: bytes, count: int) -> tuple[int, tuple[str, ...]] | None:
    """(where the name block ends, the names), or None when it is not well formed."""
    end = len(data)
    if count < 0 or 37 * count > end - _NAMES_AT:  # at least 5 bytes of name + 32 of arrays per link
        return None
    names = []
    offset = _NAMES_AT
    for _ in range(count):
        if offset + 4 > end:
            return None
        (length,) = _U32.unpack_from(data, offset)
        start = offset + 4
        offset = start + length
        if length == 0 or offset > end or data[offset - 1] != 0:
            return None
        try:
            names.append(str(data[start : offset - 1], "utf-8"))
        except UnicodeDecodeError:
            return None
    return offset, tuple(names)


class DrawEncoder:
    """Fast `lcmt_viewer_draw` encoding from arrays, byte-identical to `DRAW.encode`.

    Like the decoder it keeps the encoded name block while the names repeat.
    """

    def __init__(self) -> None:
        self._names: tuple[str, ...] = ()
        self._names_block = b""

    def encode(self, poses: LinkPoses) -> bytes:
        """The `lcmt_viewer_draw` of `poses`.

        Raises:
            EncodeError: arrays whose lengths differ from the names', or a value past float32's range.
        """
        count = len(poses)
        if poses.names != self._names:
            self._names_block = b"".join(_encode_string(name) for name in poses.names)
            self._names = tuple(poses.names)
        positions = np.asarray(poses.positions)
        quaternions = np.asarray(poses.quaternions_wxyz)
        if positions.shape != (count, 3) or quaternions.shape != (count, 4) or len(poses.robot_nums) != count:
            raise EncodeError(DRAW.type_name, "position", f"arrays do not match {count} links")
        return b"".join(
            (
                DRAW.packed_fingerprint,
                _HEADER.pack(poses.timestamp_ms, count),
                self._names_block,
                np.asarray(poses.robot_nums, dtype=">i4").tobytes(),
                _to_float32(positions, "position"),
                _to_float32(quaternions, "quaternion"),
            )
        )


def _to_float32(values: np.ndarray[Any, Any], field: str) -> bytes:
    narrowed = values.astype(">f4")
    # struct.pack('>f'), and so lcm-gen, refuses a value that only rounds to inf; numpy does not.
    if np.isinf(narrowed).any() and (np.isinf(narrowed) & ~np.isinf(values)).any():
        raise EncodeError(DRAW.type_name, field, "value out of range for float32")
    return narrowed.tobytes()


def _encode_string(text: str) -> bytes:
    data = text.encode("utf-8")
    return _U32.pack(len(data) + 1) + data + b"\0"


__all__ = ["DrawDecoder", "DrawEncoder", "poses_from_draw"]
