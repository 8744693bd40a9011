"""The tree viewer's settransform numbers and requests written the slow, obvious ways: the
references its fast path (`SettransformEncoder`) and its readers are checked against."""

from __future__ import annotations

import math
from typing import Any

import orjson

from viewer_bridge.formats.tree_viewer.envelope import encode, envelope
from viewer_bridge.formats.tree_viewer.requests import DECIMALS, draw_request
from viewer_bridge.model.scene import LinkPoses


def to_decimals(values: Any) -> list[float]:
    """Numbers as a settransform writes them: to `DECIMALS` decimals, written out by hand here."""
    return [round(float(value) * 10**DECIMALS) / 10**DECIMALS for value in values]


def reference(poses: LinkPoses, prefix: tuple[str, ...], utime: int = 0) -> bytes:
    return encode(draw_request(poses, prefix, utime))


def fixed_width_reference(poses: LinkPoses, prefix: tuple[str, ...], utime: int = 0) -> bytes:
    """The fast path's bytes, written the slow way: one number, one link at a time in Python,
    from the integer k = round(value * 10**8) (exact integer text, no float formatting)."""

    def number(value: float, separator: str) -> str:
        k = round(value * 10**DECIMALS)
        sign = "-" if math.copysign(1.0, value) < 0 else ""  # -0.0 too, as the value's own sign
        whole, fraction = divmod(abs(k), 10**DECIMALS)
        return separator + f"{sign}{whole}.".rjust(7) + f"{fraction:08d}"

    heads = [
        '{"path":'
        + orjson.dumps([*prefix, str(int(robot_num)), name]).decode()
        + ',"transform":{"translation":['
        for name, robot_num in zip(poses.names, poses.robot_nums.tolist(), strict=True)
    ]
    width = -(-max(len(head.encode()) for head in heads) // 8) * 8
    rows = []
    for index, (head, position, quaternion) in enumerate(
        zip(heads, poses.positions.tolist(), poses.quaternions_wxyz.tolist(), strict=True)
    ):
        values = [number(value, "," if place else " ") for place, value in enumerate(position)]
        values.append('],"quaternion":[')
        values += [number(value, "," if place else " ") for place, value in enumerate(quaternion)]
        end = "]}}," if index < len(heads) - 1 else "]}}"
        rows.append(" " * (width - len(head.encode())) + head + "".join(values) + end.ljust(8))
    utime = utime or poses.timestamp_ms * 1000
    text = f'{{"timestamp":{utime},"setgeometry":[],"settransform":[' + "".join(rows) + '],"delete":[]}'
    return envelope(text.encode(), utime)
