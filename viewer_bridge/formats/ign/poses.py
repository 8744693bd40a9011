"""Link poses to and from ign/gz `Pose_V` and the legacy `PosesStamped`.

A draw is written by `PosesEncoder` straight from its arrays, byte for byte what protobuf writes
for the same message (the protobuf-object reference is in tests/formats/ign/oracle.py); the
translators' messages are read back with `poses_from_pose_v`.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from viewer_bridge.formats import protowire as wire
from viewer_bridge.formats.ign.schema import field_number
from viewer_bridge.model.pose_math import pose_rows_xyzw
from viewer_bridge.model.scene import FloatArray, LinkPoses, link_poses_from_xyzw
from viewer_bridge.model.sim_time import ms_from_sec_nsec, sec_nsec_from_ms

_HEADER, _HEADER_STAMP = field_number("Pose_V", "header"), field_number("Header", "stamp")
# The keys of Time.sec and Time.nsec, varints each left out when 0 (proto3).
_TIME_SEC, _TIME_NSEC = (wire.key(field_number("Time", name), wire.VARINT) for name in ("sec", "nsec"))
_DOUBLE_FIELDS = tuple(field_number("Vector3d", axis) for axis in "xyz") + tuple(
    field_number("Quaternion", axis) for axis in "xyzw"
)  # the 7 doubles of a pose, in `pose_rows_xyzw` order: position x y z, orientation x y z w


class PosesEncoder:
    """draw arrays -> `Pose_V` (or `PosesStamped`) bytes, byte for byte as protobuf writes them
    from message objects (tests/formats/ign/oracle.py builds those), without a message per link.

    proto3 leaves out a double that is +0.0 and an id that is 0, so the bytes of a pose depend
    on its name, its index and which of its seven doubles are zero. For one list of names and
    one such pattern the poses are laid out once, with the byte offset of every double written;
    a draw then copies that template and writes its doubles, and only a new pattern (a value
    becoming exactly 0 or leaving 0) lays the poses out again.
    """

    def __init__(self, message: str = "Pose_V") -> None:
        """`message` is `Pose_V` or `PosesStamped` (the package, ignition or gz, is not in the bytes)."""
        self.message = message
        self._pattern: tuple[tuple[str, ...], bytes] = ((), b"")
        self._layout = _PosesLayout([], np.zeros((0, 7), dtype=bool))
        self._lock = threading.Lock()  # routes on several threads may share an encoder

    def encode(self, poses: LinkPoses) -> bytes:
        """The `Pose_V` (or `PosesStamped`) of `poses`, stamped with their sim time; it raises
        nothing of its own (the arrays are a decoded draw's)."""
        rows = pose_rows_xyzw(poses.positions, poses.quaternions_wxyz)
        written = rows.view(np.uint64) != 0  # +0.0 is all zero bits; -0.0 is written
        zeros = written.tobytes()
        head = self._head(poses.timestamp_ms)
        with self._lock:
            names, known_zeros = self._pattern
            if zeros != known_zeros or (poses.names is not names and poses.names != names):
                self._layout = _PosesLayout(self._lay_out(poses.names, written), written)
                self._pattern = (poses.names, zeros)
            return b"".join((head, self._layout.write(rows).data))

    def _head(self, timestamp_ms: int) -> bytes:
        """The header with the stamp (and for `PosesStamped` the time field): before the poses."""
        seconds, nanoseconds = sec_nsec_from_ms(timestamp_ms)
        time = (_TIME_SEC + wire.varint(seconds) if seconds else b"") + (
            _TIME_NSEC + wire.varint(nanoseconds) if nanoseconds else b""
        )
        head = wire.length_delimited(_HEADER, wire.length_delimited(_HEADER_STAMP, time))
        if self.message == "PosesStamped":
            head += wire.length_delimited(field_number(self.message, "time"), time)
        return head

    def _lay_out(self, names: Sequence[str], written: npt.NDArray[np.bool_]) -> list[tuple[bytes, list[int]]]:
        """Every pose's bytes (zeros for its doubles) and where its written doubles sit in them."""
        entries = []
        pose_field = field_number(self.message, "pose")
        for index, (name, present) in enumerate(zip(names, written.tolist(), strict=True)):
            position, position_places = _doubles(_DOUBLE_FIELDS[:3], present[:3])
            orientation, orientation_places = _doubles(_DOUBLE_FIELDS[3:], present[3:])
            head = wire.length_delimited(field_number("Pose", "name"), name.encode())
            head += wire.varint_field(field_number("Pose", "id"), index)
            position_key = wire.key(field_number("Pose", "position"), wire.LENGTH_DELIMITED)
            position_head = position_key + wire.varint(len(position))
            orientation_key = wire.key(field_number("Pose", "orientation"), wire.LENGTH_DELIMITED)
            orientation_head = orientation_key + wire.varint(len(orientation))
            body = b"".join((head, position_head, position, orientation_head, orientation))
            entry_head = wire.key(pose_field, wire.LENGTH_DELIMITED) + wire.varint(len(body))
            at = len(entry_head) + len(head) + len(position_head)
            places = [at + place for place in position_places]
            at += len(position) + len(orientation_head)
            places += [at + place for place in orientation_places]
            entries.append((entry_head + body, places))
        return entries


class _PosesLayout:
    """The poses' bytes for one names-and-zeros pattern, kept in a buffer whose doubles a draw
    overwrites (all of them, so the rest stays the template).

    The doubles sit at any byte offset; numpy writes them as float64 through 8 views of the
    buffer, one per offset modulo 8, which is several times faster than writing 8 bytes each.
    """

    def __init__(self, entries: list[tuple[bytes, list[int]]], written: npt.NDArray[np.bool_]) -> None:
        places, size = [], 0
        for entry, entry_places in entries:
            places += [size + place for place in entry_places]
            size += len(entry)
        self.buffer = np.frombuffer(bytearray(b"".join(entry for entry, _ in entries)), dtype=np.uint8)
        offsets = np.asarray(places, dtype=np.intp)
        sources = np.flatnonzero(written.reshape(-1))  # which of the N x 7 values, in `offsets` order
        by_residue = np.argsort(offsets % 8, kind="stable")
        self.sources = sources[by_residue]  # gathered in one go, then written a residue at a time
        offsets = offsets[by_residue]
        bounds = np.searchsorted(offsets % 8, np.arange(9))
        self.views = []
        for residue in range(8):
            part = slice(bounds[residue], bounds[residue + 1])
            words = (len(self.buffer) - residue) // 8
            view = self.buffer[residue : residue + 8 * words].view("<f8")
            self.views.append((view, (offsets[part] - residue) // 8, part))

    def write(self, rows: FloatArray) -> npt.NDArray[np.uint8]:
        values = rows.reshape(-1)[self.sources]
        for view, slots, part in self.views:
            view[slots] = values[part]
        return self.buffer


def _doubles(fields: Sequence[int], present: Sequence[bool]) -> tuple[bytes, list[int]]:
    """The doubles of a message with their keys (zeros for now), and where each written one sits."""
    out, places = b"", []
    for field, written in zip(fields, present, strict=True):
        if written:
            out += wire.key(field, wire.FIXED64)
            places.append(len(out))
            out += bytes(8)
    return out, places


def _xyzw(pose: Any) -> list[float]:
    if not pose.HasField("orientation"):
        return [0.0, 0.0, 0.0, 1.0]
    orientation = pose.orientation
    return [orientation.x, orientation.y, orientation.z, orientation.w]


def poses_from_pose_v(message: Any, robot_nums: Mapping[str, int] | None = None) -> LinkPoses:
    """A `Pose_V` or `PosesStamped` back as link poses (names from `Pose.name`).

    `robot_nums` (link name -> model instance, e.g. from the scene's load) fills what the
    message does not carry; links it lacks get 0. A Pose without an orientation is not rotated
    (the identity, as every gz tool reads it). Raises `SceneError` for a non-finite position or
    an orientation given that is not a rotation.
    """
    names = [p.name for p in message.pose]
    positions = [[p.position.x, p.position.y, p.position.z] for p in message.pose]
    xyzw = [_xyzw(p) for p in message.pose]
    numbers = [(robot_nums or {}).get(name, 0) for name in names]
    stamp = message.header.stamp
    timestamp_ms = ms_from_sec_nsec(stamp.sec, stamp.nsec)
    return link_poses_from_xyzw(timestamp_ms, names, numbers, positions, xyzw, "pose")


__all__ = [
    "PosesEncoder",
    "poses_from_pose_v",
]
