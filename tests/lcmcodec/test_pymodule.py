"""lcm-gen'd Python classes read as definitions: Drake's own, by import name."""

from __future__ import annotations

import drake
import pytest

from viewer_bridge.errors import SchemaError
from viewer_bridge.lcmcodec.codecs import STRUCTS
from viewer_bridge.lcmcodec.pymodule import is_lcm_class, struct_from_class, structs_from_module
from viewer_bridge.lcmcodec.schema import fingerprint


def test_every_drake_class_fingerprint_is_the_one_its_description_gives() -> None:
    loaded = structs_from_module("drake")
    names = {f"drake.{name}" for name in dir(drake) if is_lcm_class(getattr(drake, name))}
    assert len(names) > 40 and set(loaded) == names
    structs = {name: definition for name, (definition, _) in loaded.items()}
    for name, (definition, packed) in loaded.items():
        assert fingerprint(definition, structs).to_bytes(8, "big") == packed, name


def test_drakes_classes_describe_what_our_schemas_say() -> None:
    loaded = structs_from_module("drake")
    for name, ours in STRUCTS.items():
        if name in loaded:
            theirs = loaded[name][0]
            assert theirs.members == ours.members, name
            assert {c.name: c.value for c in theirs.constants} == {c.name: c.value for c in ours.constants}


def test_a_module_of_one_type_pulls_in_the_types_it_nests() -> None:
    loaded = structs_from_module("drake.lcmt_robot_plan")
    assert set(loaded) == {"drake.lcmt_robot_plan", "drake.lcmt_robot_state"}
    plan = loaded["drake.lcmt_robot_plan"][0]
    assert plan.package == "drake" and plan.where == "module drake.lcmt_robot_plan"
    assert [(m.name, m.type_name, [d.size for d in m.dims]) for m in plan.members] == [
        ("utime", "int64_t", []), ("num_states", "int32_t", []), ("plan", "drake.lcmt_robot_state", ["num_states"]),
    ]  # fmt: skip


def test_constants_are_read_from_the_class() -> None:
    geometry = structs_from_module("drake.lcmt_viewer_geometry_data")["drake.lcmt_viewer_geometry_data"][0]
    constants = {c.name: (c.type_name, c.value) for c in geometry.constants}
    assert constants["BOX"] == ("int32_t", 1) and constants["MESH"] == ("int32_t", 4)


def test_modules_without_lcm_classes_are_refused() -> None:
    with pytest.raises(SchemaError, match="module os.path: holds no lcm-gen'd Python class"):
        structs_from_module("os.path")


def _lcm_class(members: list[str], **constants: object) -> type:
    """A class that describes itself as lcm-gen's do (one int32_t per member), with `constants`."""
    namespace: dict[str, object] = {
        "__slots__": members,
        "__typenames__": ["int32_t"] * len(members),
        "__dimensions__": [None] * len(members),
        "_get_packed_fingerprint": staticmethod(lambda: bytes(8)),
        **constants,
    }
    return type("handmade_t", (), namespace)


@pytest.mark.parametrize(
    ("cls", "reason"),
    [
        (_lcm_class(["a"], LIMIT=float("inf")), "handmade_t: inf is not a finite double"),
        (_lcm_class(["a"], GAP=float("nan")), "handmade_t: nan is not a finite double"),
        (_lcm_class(["a", "to_dict"]), "handmade_t: a member name 'to_dict' is the name of an attribute"),
        (_lcm_class(["a"], encode=3), "handmade_t: a constant name 'encode' is the name of an attribute"),
    ],
)
def test_a_class_the_generated_codecs_could_not_copy_is_refused_naming_its_module(
    cls: type, reason: str
) -> None:
    with pytest.raises(SchemaError) as caught:
        struct_from_class(cls, "module handmade")
    assert str(caught.value).startswith(f"module handmade: {reason}")
    assert struct_from_class(_lcm_class(["a", "b"], LIMIT=2.5), "module handmade").constants[0].value == 2.5
