"""ROS 2 CDR -> LCM for any ROS 2 type mapped by `from_ros` (docs/PROTOCOLS.md section 14).

The code is `cdr_to_lcm`'s one generator, given the mapping's wire structs, and is run by the same
`LcmEncoder` (header, trailing bytes). What differs from an LCM type's own ROS 2 form is the
mapping itself: here the CDR is the ROS 2 type's, and LCM gets what ROS 2 does not send, a length
field before each sequence, and wider integers for the unsigned ones LCM lacks. Once a message has
passed that code, its layout is kept (`layout`): the next of the same shape is one call of the
compiled mover.

Errors are `DecodeError`s with the ROS 2 type, the field path and the byte offset (from the
first byte after the 4-byte encapsulation header).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Mapping

from viewer_bridge.lcmcodec.cdr_to_lcm import WIRE, LcmEncoder, compile_wire
from viewer_bridge.lcmcodec.from_ros import LcmFromRos, RosField, RosStruct
from viewer_bridge.lcmcodec.layout import learn_ros_layout

__all__ = ["compile_ros_encoders"]

_TEXT_MIN = {"string": 5, "wstring": 4}  # count and NUL; count only


def compile_ros_encoders(
    mapping: LcmFromRos, ros_names: Iterable[str], keep_layouts: bool = True
) -> dict[str, LcmEncoder]:
    """The CDR -> LCM encoders of the mapped ROS 2 types `ros_names`, by ROS 2 name. Each keeps the
    layouts of the messages it has converted (`layout`) unless `keep_layouts` is False: then
    every message takes the generated code (as the first of each shape does)."""
    names = list(ros_names)
    bodies = compile_wire(mapping.lcm, mapping.structs, names, _min_sizes(mapping.structs))
    learners = {name: functools.partial(learn_ros_layout, mapping.structs, WIRE, name, mapping.packed_fingerprint(name))
                for name in names}  # fmt: skip
    return {name: LcmEncoder(name, mapping.packed_fingerprint(name), bodies[name],
                             learners[name] if keep_layouts else None)
            for name in names}  # fmt: skip


def _min_sizes(structs: Mapping[str, RosStruct]) -> dict[str, int]:
    """The fewest CDR bytes of each type (padding aside): the bound that refuses impossible counts."""
    sizes: dict[str, int] = {}

    def size_of(name: str) -> int:
        if name not in sizes:
            sizes[name] = sum(_field_min(f, size_of) for f in structs[name].fields)
        return sizes[name]

    for name in structs:
        size_of(name)
    return sizes


def _field_min(ros_field: RosField, size_of: Callable[[str], int]) -> int:
    if ros_field.kind == "sequence":
        return 4
    count = ros_field.count if ros_field.kind == "array" else 1
    if ros_field.nested:
        return count * size_of(ros_field.nested)
    return count * (_TEXT_MIN.get(ros_field.base) or WIRE[ros_field.base][0])
