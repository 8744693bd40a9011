"""A scene as tree viewer requests: a load as delete + setgeometry, a draw as settransforms.

How a scene is laid out in the tree: each link is the node
`[*prefix, str(robot_num), link.name]`, whose transform is the link's world pose; each geometry
is a child `[..., str(index)]` whose setgeometry `transform` is its pose in the link frame.
Quaternions are `[w, x, y, z]`, as in Drake. A new load deletes `prefix` first.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from typing import Any

import numpy as np
import numpy.typing as npt
import orjson

from viewer_bridge.formats.mappings import FormatTables
from viewer_bridge.formats.tree_viewer.common import DEFAULT_PREFIX
from viewer_bridge.formats.tree_viewer.envelope import Request, encode, envelope
from viewer_bridge.model.scene import (
    FloatArray,
    Geometry,
    Line,
    Link,
    LinkPoses,
    PointCloud,
    Pose,
    Scene,
    Shape,
    TriangleMesh,
)
from viewer_bridge.model.skipped import per_geometry


def _mesh_data(shape: TriangleMesh) -> dict[str, Any]:
    return {"vertices": shape.vertices.tolist(), "faces": shape.triangles.tolist()}


def _pointcloud(shape: PointCloud) -> dict[str, Any]:
    channels = {name: list(values) for name, values in shape.channels.items()}
    if shape.colors is not None:
        channels["rgb"] = shape.colors.tolist()
    return {"points": shape.points.tolist(), "channels": channels}


def _line(shape: Line) -> dict[str, Any]:
    return {
        "points": shape.points.tolist(),
        "radius": shape.radius,
        "closed": shape.closed,
        "start_head": shape.start_head,
        "end_head": shape.end_head,
        "head_radius": shape.head_radius,
        "head_length": shape.head_length,
    }


TABLES = FormatTables("tree_viewer", {"mesh_data": _mesh_data, "pointcloud": _pointcloud, "line": _line})


def transform(pose: Pose) -> dict[str, list[float]]:
    return {"translation": list(pose.position), "quaternion": list(pose.quaternion_wxyz)}


def link_path(link: Link, prefix: Sequence[str] = DEFAULT_PREFIX) -> list[str]:
    return [*prefix, str(link.robot_num), link.name]


def geometry_command(shape: Shape, pose: Pose, color: Sequence[float]) -> dict[str, Any]:
    """The `geometry` object of a setgeometry for one shape (see mappings/tree_viewer.yaml)."""
    ((rule, lowered, lowered_pose),) = TABLES["geometry"].expand(shape, pose)
    return {
        "type": rule.type_code,
        **rule.values(lowered),
        "color": list(color),
        "transform": transform(lowered_pose),
    }


def load_requests(scene: Scene, prefix: Sequence[str] = DEFAULT_PREFIX, utime: int = 0) -> list[Request]:
    """A load as two requests: delete the old tree under `prefix`, then set every geometry.

    Two requests rather than one, because a viewer may apply `delete` after `setgeometry`
    within a request. If the scene has poses, the second request also sets the links' transforms.
    A geometry the format cannot hold (an in-memory mesh trimesh cannot read) is skipped.
    """
    commands = []
    for link in scene.links:
        path = link_path(link, prefix)

        def setgeometry(index: int, geometry: Geometry, path: list[str] = path) -> dict[str, Any]:
            command = geometry_command(geometry.shape, geometry.pose, geometry.color)
            return {"path": [*path, str(index)], "geometry": command}

        commands += per_geometry(link, setgeometry)
    settransform = draw_request(scene.poses, prefix, utime)["settransform"] if scene.poses else []
    return [
        _request(utime, delete=[{"path": list(prefix)}]),
        _request(utime, setgeometry=commands, settransform=settransform),
    ]


def draw_request(poses: LinkPoses, prefix: Sequence[str] = DEFAULT_PREFIX, utime: int = 0) -> Request:
    """A draw as one request of `settransform`s, one per link (robot_num from the draw itself).

    Its numbers are rounded to `DECIMALS` decimals (see `settransform_values`).
    """
    values = settransform_values(poses).tolist()
    commands = [
        {
            "path": [*prefix, str(int(robot_num)), name],
            "transform": {"translation": row[:3], "quaternion": row[3:]},
        }
        for name, robot_num, row in zip(poses.names, poses.robot_nums.tolist(), values, strict=True)
    ]
    return _request(utime or poses.timestamp_ms * 1000, settransform=commands)


# A settransform writes its numbers with 8 decimals: 5e-9 m or 5e-9 of a unit quaternion at most,
# under what a viewer can show and close to a float32's resolution (Drake's draws are float32).
# Shortest round-trip text costs about 45 ns a number even in orjson; fixed decimals let a draw
# be written from digit tables with a few numpy operations (`SettransformEncoder`).
DECIMALS = 8
_SCALE = 10.0**DECIMALS
# Beyond this a double has no 8th decimal to round to, and value * 10**8 could overflow to inf.
_ROUNDED_BELOW = 1e7


def settransform_values(poses: LinkPoses) -> FloatArray:
    """The N x 7 numbers of a draw's settransforms, [x, y, z, w, qx, qy, qz] per link, rounded to
    `DECIMALS` decimals (the double nearest to k / 10**DECIMALS, which is what parsing that
    decimal text gives); numbers of 10**7 or more in magnitude are left as they are."""
    values = np.concatenate((poses.positions, poses.quaternions_wxyz), axis=1, dtype=np.float64)
    with np.errstate(over="ignore"):  # the huge, kept as they are
        rounded = np.rint(values * _SCALE) / _SCALE
    return np.where(np.abs(values) < _ROUNDED_BELOW, rounded, values)


class SettransformEncoder:
    """A draw -> the envelope of its settransform request: the JSON values of
    `encode(draw_request(...))`, written faster.

    The JSON around the numbers depends only on the links (names, robot_nums) and the prefix,
    so it is kept per set of links as a table with one fixed-width row per link: the link's
    head (space-padded; JSON allows spaces between tokens), then eight 16-byte slots, the
    fourth holding `],"quaternion":[` and the others a number each, then the row's end.
    A number's slot is its separator, its sign and integer part right-aligned in spaces, the
    point, and the 8 decimals: three lookups in tables of digit groups (`_NumberTables`).
    A draw fills the slots with a few whole-array numpy operations and the request is the
    table's bytes. A draw with a number of 9,999 or more in magnitude is written by orjson.
    """

    _SLOT = 16
    _QUATERNION_SLOT = b'],"quaternion":['
    _ROW_END = (b"]}},", b"]}}")  # (between rows, after the last)
    _ROW_END_WIDTH = 8

    def __init__(self, prefix: Sequence[str] = DEFAULT_PREFIX) -> None:
        self.prefix = tuple(prefix)
        self._links: tuple[tuple[str, ...], bytes] | None = None
        self._rows = np.zeros((0, 0), np.uint8)
        self._slots = np.zeros((0, 8, 2), np.uint64)

    def encode(self, poses: LinkPoses, utime: int = 0) -> bytes:
        """The tree viewer's `settransform` request of `poses` as JSON bytes, `timestamp` `utime`
        (0: their sim time); it raises nothing of its own (the arrays are a decoded draw's)."""
        utime = int(utime or poses.timestamp_ms * 1000)
        start = b'{"timestamp":%d,"setgeometry":[],"settransform":[' % utime
        end = b'],"delete":[]}'
        if not len(poses):
            return envelope(start + end, utime)
        self._layout(poses)
        if not _number_tables().fill(self._slots, poses.positions, poses.quaternions_wxyz):
            return encode(draw_request(poses, self.prefix, utime), utime)
        return envelope(b"".join((start, self._rows.tobytes(), end)), utime)

    def _layout(self, poses: LinkPoses) -> None:
        robot_nums = poses.robot_nums.tobytes()
        if self._links is not None and self._links[1] == robot_nums and self._links[0] == poses.names:
            return
        heads = [
            b'{"path":'
            + orjson.dumps([*self.prefix, str(int(robot_num)), name])
            + b',"transform":{"translation":['
            for name, robot_num in zip(poses.names, poses.robot_nums.tolist(), strict=True)
        ]
        head_width = -(-max(map(len, heads)) // 8) * 8  # a multiple of 8, so the slots are uint64-aligned
        numbers = head_width + 8 * self._SLOT
        rows = np.full((len(heads), numbers + self._ROW_END_WIDTH), ord(" "), np.uint8)
        for row, head in zip(rows, heads, strict=True):
            row[head_width - len(head) : head_width] = np.frombuffer(head, np.uint8)
            row[numbers : numbers + 4] = np.frombuffer(self._ROW_END[0], np.uint8)
        rows[-1, numbers : numbers + 4] = np.frombuffer(self._ROW_END[1].ljust(4), np.uint8)
        rows[:, head_width + 3 * self._SLOT : head_width + 4 * self._SLOT] = np.frombuffer(
            self._QUATERNION_SLOT, np.uint8
        )
        self._rows = rows
        self._slots = rows.view(np.uint64)[:, head_width // 8 : numbers // 8].reshape(len(heads), 8, 2)
        self._links = (poses.names, robot_nums)


class _NumberTables:
    """The digit tables that write settransform numbers into 16-byte slots (`SettransformEncoder`).

    A slot is two uint64s. The first is 8 characters: the separator (a space before the first
    number of a list, else a comma), the sign and integer part right-aligned, and the point:
    one entry per (separator, sign, integer part < 10,000). The second is two entries of a
    table of the 4-digit groups 0000 to 9999 (uint32 each), the decimals.
    """

    _WHOLE_LIMIT = 10_000
    _GROUP = 10_000.0
    # Per number of [x, y, z, w, qx, qy, qz]: 1 where a comma comes before it.
    _AFTER_COMMA = np.array([0, 1, 1, 0, 1, 1, 1], np.float64)

    def __init__(self) -> None:
        wholes = [
            lead + b"%s%d." % (sign, whole)
            for lead in (b" ", b",")
            for sign in (b"", b"-")
            for whole in range(self._WHOLE_LIMIT)
        ]
        self.wholes = np.frombuffer(b"".join(text[:1] + text[1:].rjust(7) for text in wholes), np.uint64)
        self.groups = np.frombuffer(b"".join(b"%04d" % group for group in range(10_000)), np.uint32)
        self.offsets = self._AFTER_COMMA * (2 * self._WHOLE_LIMIT)

    def fill(self, slots: npt.NDArray[np.uint64], positions: FloatArray, quaternions: FloatArray) -> bool:
        """Writes a draw's numbers into `slots` (N x 8 x 2, slot 3 left alone); False, writing
        nothing, when a number is too large for a slot."""
        values = np.concatenate((positions, quaternions), axis=1, dtype=np.float64)
        magnitude = np.abs(values)
        if not magnitude.max() < self._WHOLE_LIMIT - 1:  # also False for NaN; the rest fit, rounded
            return False
        magnitude = np.rint(magnitude * _SCALE)  # |k|: rint rounds half to even, symmetric in sign
        whole = np.floor(magnitude / _SCALE)  # exact: k / 1e8 is never rounded up to the next integer
        fraction = magnitude - whole * _SCALE
        high = np.floor(fraction / self._GROUP)
        low = fraction - high * self._GROUP
        whole += self.offsets
        whole += np.signbit(values) * float(self._WHOLE_LIMIT)  # -0.0 too: a negative rounded to 0
        texts = np.empty((len(values), 7, 2), np.uint64)
        texts[:, :, 0] = self.wholes.take(whole.astype(np.intp))
        decimals = texts.view(np.uint32).reshape(len(values), 7, 4)
        decimals[:, :, 2] = self.groups.take(high.astype(np.intp))
        decimals[:, :, 3] = self.groups.take(low.astype(np.intp))
        slots[:, 0:3] = texts[:, 0:3]
        slots[:, 4:8] = texts[:, 3:7]
        return True


@cache
def _number_tables() -> _NumberTables:
    return _NumberTables()


def _request(utime: int, **commands: list[dict[str, Any]]) -> Request:
    return {
        "timestamp": int(utime),
        "setgeometry": commands.get("setgeometry", []),
        "settransform": commands.get("settransform", []),
        "delete": commands.get("delete", []),
    }


__all__ = [
    "DECIMALS",
    "DEFAULT_PREFIX",
    "TABLES",
    "SettransformEncoder",
    "draw_request",
    "geometry_command",
    "link_path",
    "load_requests",
    "settransform_values",
    "transform",
]
