"""Hypothesis strategies that build random messages of any schema in lcmtypes/.

They are derived from the parsed definitions, so a new `.lcm` file is covered without new code.
Each example is a pair (our message, the equivalent lcm-gen object).
"""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from bridge.lcmcodec import CODECS, LcmMessage
from bridge.lcmcodec.schema import Member, StructDef

INT_RANGES = {"int8_t": 8, "int16_t": 16, "int32_t": 32, "int64_t": 64}


def _leaf(type_name: str) -> st.SearchStrategy[Any]:
    if type_name in INT_RANGES:
        bits = INT_RANGES[type_name]
        return st.integers(-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    if type_name == "float":
        return st.floats(width=32, allow_nan=False, allow_infinity=False)
    if type_name == "double":
        return st.floats(allow_nan=False, allow_infinity=False)
    if type_name == "boolean":
        return st.booleans()
    if type_name == "string":
        return st.text(max_size=12)
    if type_name == "byte":
        return st.integers(0, 255)
    return message_pairs(CODECS[type_name].definition)


def _count_members(struct: StructDef) -> set[str]:
    return {dim.size for member in struct.members for dim in member.dims if dim.is_variable}


def _array(member: Member, shape: list[int]) -> st.SearchStrategy[Any]:
    if len(shape) == 1 and member.type_name == "byte":
        return st.binary(min_size=shape[0], max_size=shape[0]).map(lambda data: (data, data))
    inner = _array(member, shape[1:]) if len(shape) > 1 else _leaf(member.type_name).map(_pair)
    return st.lists(inner, min_size=shape[0], max_size=shape[0]).map(
        lambda items: ([ours for ours, _ in items], [theirs for _, theirs in items])
    )


def _pair(value: Any) -> tuple[Any, Any]:
    return (
        value
        if isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], LcmMessage)
        else (value, value)
    )


@st.composite
def message_pairs(
    draw: st.DrawFn, struct: StructDef, lcmgen: dict[str, type] | None = None
) -> tuple[Any, Any]:
    """One random message of `struct` and, when `lcmgen` is given, lcm-gen's equal object."""
    lcmgen = lcmgen if lcmgen is not None else _LCMGEN
    counts = _count_members(struct)
    ours: dict[str, Any] = {}
    theirs: dict[str, Any] = {}
    for member in struct.members:
        if member.name in counts:
            value = draw(st.integers(0, 4))
            ours[member.name] = theirs[member.name] = value
            continue
        if member.dims:
            shape = [ours[dim.size] if dim.is_variable else int(dim.size) for dim in member.dims]
            ours[member.name], theirs[member.name] = draw(_array(member, shape))
        else:
            ours[member.name], theirs[member.name] = _pair(draw(_leaf(member.type_name)))
    message = CODECS[struct.full_name].message_class(**ours)
    other = lcmgen[struct.full_name]()
    for name, value in theirs.items():
        setattr(other, name, value)
    return message, other


_LCMGEN: dict[str, type] = {}


def use_lcmgen(classes: dict[str, type]) -> None:
    """Tell the strategies which lcm-gen classes to build the twin objects from."""
    _LCMGEN.update(classes)
