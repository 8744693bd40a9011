"""Hypothesis strategies that build random messages of any schema in lcmtypes/.

They are derived from the parsed definitions, so a new `.lcm` file is covered without new code.
Each example is a pair (our message, the equivalent lcm-gen object).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import strategies as st

from viewer_bridge.lcmcodec.codecs import CODECS
from viewer_bridge.lcmcodec.schema import Member, StructDef
from viewer_bridge.lcmcodec.serde import LcmMessage
from viewer_bridge.model.scene import (
    Box,
    Capsule,
    Cylinder,
    Ellipsoid,
    Geometry,
    Link,
    LinkPoses,
    MeshFile,
    Pose,
    Scene,
    Shape,
    Sphere,
    TriangleMesh,
)

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


# --- scenes and poses for the translators' round trips ------------------------------------------

finite = st.floats(-100, 100, allow_nan=False, allow_infinity=False)
positive = st.floats(0.001, 10, allow_nan=False, allow_infinity=False)
unit_interval = st.floats(0, 1, width=32)


@st.composite
def unit_quaternions(draw: st.DrawFn) -> tuple[float, float, float, float]:
    """A w-first unit quaternion."""
    values = np.array(
        draw(st.tuples(finite, finite, finite, finite).filter(lambda q: sum(v * v for v in q) > 1e-3))
    )
    w, x, y, z = (values / np.linalg.norm(values)).tolist()
    return (w, x, y, z)


def vectors(elements: st.SearchStrategy[float] = finite) -> st.SearchStrategy[tuple[float, float, float]]:
    return st.tuples(elements, elements, elements)


poses = st.builds(Pose, vectors(), unit_quaternions())

link_names = st.text(st.characters(min_codepoint=33, max_codepoint=0x2FF), min_size=1, max_size=10).map(
    lambda text: f"plant::{text}"
)


@st.composite
def triangle_meshes(draw: st.DrawFn) -> TriangleMesh:
    vertex_count = draw(st.integers(3, 6))
    vertices = draw(st.lists(vectors(), min_size=vertex_count, max_size=vertex_count))
    triangles = draw(st.lists(st.tuples(*[st.integers(0, vertex_count - 1)] * 3), min_size=1, max_size=4))
    return TriangleMesh(np.array(vertices, dtype=np.float64), np.array(triangles, dtype=np.int64))


# The shapes every reverse direction can read back exactly (no lowering on the way out).
invertible_shapes = st.one_of(
    st.builds(Box, vectors(positive)),
    st.builds(Sphere, positive),
    st.builds(Cylinder, positive, positive),
    st.builds(Capsule, positive, positive),
    st.builds(Ellipsoid, vectors(positive)),
    st.builds(
        MeshFile,
        st.text(
            st.characters(exclude_characters="\0/", exclude_categories=("Cs",)), min_size=1, max_size=12
        ).map(lambda name: f"/meshes/{name}.obj"),
        vectors(positive),
    ),
    triangle_meshes(),
)

colors = st.tuples(unit_interval, unit_interval, unit_interval, unit_interval)


@st.composite
def scenes(draw: st.DrawFn, shapes: st.SearchStrategy[Shape] = invertible_shapes) -> Scene:
    """A scene of uniquely named links, each with a few posed, coloured geometries."""
    names = draw(st.lists(link_names, min_size=1, max_size=4, unique=True))
    links = []
    for name in names:
        geometries = draw(st.lists(st.builds(Geometry, shapes, poses, colors), max_size=3))
        links.append(Link(name, draw(st.integers(0, 5)), tuple(geometries)))
    return Scene(tuple(links))


@st.composite
def link_poses(draw: st.DrawFn, max_links: int = 6) -> LinkPoses:
    names = tuple(draw(st.lists(link_names, max_size=max_links, unique=True)))
    count = len(names)
    return LinkPoses(
        timestamp_ms=draw(st.integers(0, 2**40)),
        names=names,
        robot_nums=np.array(
            draw(st.lists(st.integers(0, 2**20), min_size=count, max_size=count)), dtype=np.int32
        ),
        positions=np.array(
            draw(st.lists(vectors(), min_size=count, max_size=count)), dtype=np.float64
        ).reshape(-1, 3),
        quaternions_wxyz=np.array(
            draw(st.lists(unit_quaternions(), min_size=count, max_size=count)), dtype=np.float64
        ).reshape(-1, 4),
    )
