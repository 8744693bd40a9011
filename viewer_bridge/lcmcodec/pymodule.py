"""LCM types from lcm-gen'd Python classes, by import name, as the same `StructDef`s a `.lcm` file gives.

lcm-gen's Python classes describe themselves: `__slots__` (the members in wire order),
`__typenames__` (a primitive or a full type name), `__dimensions__` (None, or one item per
dimension: an int, or the name of the length member), constants as class attributes, and
`_get_packed_fingerprint()`. A constant's declared type is not kept by lcm-gen; we call an int
constant `int32_t` when it fits (else `int64_t`) and a float constant `double`.

A name may be a module of one type (`exlcm.example_t`) or a package whose namespace holds them
(`drake`: pydrake ships Drake's types so); a member's type from another package is imported by its
full name.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

from viewer_bridge.errors import SchemaError
from viewer_bridge.lcmcodec.schema import (
    INTEGER_RANGES,
    Constant,
    Dimension,
    Member,
    StructDef,
    constant_problem,
    name_problem,
)

LoadedClass = tuple[StructDef, bytes]  # the definition and the class's own packed fingerprint


def is_lcm_class(value: object) -> bool:
    """True for a class lcm-gen wrote (it has the three descriptions and a fingerprint)."""
    return (
        inspect.isclass(value)
        and all(hasattr(value, name) for name in ("__slots__", "__typenames__", "__dimensions__"))
        and callable(getattr(value, "_get_packed_fingerprint", None))
    )


def structs_from_module(name: str, search: Path | None = None) -> dict[str, LoadedClass]:
    """Every lcm-gen'd class of module `name` and, transitively, the types their members name;
    `search`: a folder to import it from (as well as sys.path)."""
    source = f"module {name}" if search is None else f"module {name} in {search}"
    if search is not None:
        sys.path.insert(0, str(search))
    try:
        module = importlib.import_module(name)
        return _classes(module, source)
    except SchemaError:
        raise
    except Exception as error:  # noqa: BLE001  (an import runs arbitrary code; report, do not crash)
        raise SchemaError(source, 0, f"cannot import: {type(error).__name__}: {error}") from None
    finally:
        if search is not None:
            sys.path.remove(str(search))


def _classes(module: ModuleType, source: str) -> dict[str, LoadedClass]:
    found: dict[str, LoadedClass] = {}
    pending = [
        value for child in _with_subpackages(module) for value in vars(child).values() if is_lcm_class(value)
    ]
    if not pending:
        raise SchemaError(source, 0, "holds no lcm-gen'd Python class")
    while pending:
        cls = pending.pop()
        definition = struct_from_class(cls, source)
        if definition.full_name in found:
            continue
        found[definition.full_name] = (definition, bytes(cls._get_packed_fingerprint()))
        for member in definition.members:
            if not member.is_primitive and member.type_name not in found:
                pending.append(_import_class(member.type_name, cls, source))
    return found


def _with_subpackages(module: ModuleType) -> list[ModuleType]:
    """The module and, for a package, its subpackages at any depth (lcm-gen writes package `a.b`
    as folders `a/b/`, with nothing but the subpackage in `a`)."""
    modules = [module]
    for info in pkgutil.walk_packages(getattr(module, "__path__", []), module.__name__ + "."):
        if info.ispkg:
            modules.append(importlib.import_module(info.name))
    return modules


def struct_from_class(cls: Any, source: str) -> StructDef:
    """The definition of one lcm-gen'd class."""
    package, name = _full_name(cls)
    slots, typenames, dimensions = list(cls.__slots__), list(cls.__typenames__), list(cls.__dimensions__)
    if not len(slots) == len(typenames) == len(dimensions):
        raise SchemaError(
            source, 0, f"{cls.__name__}: __slots__, __typenames__, __dimensions__ differ in length"
        )
    members = tuple(
        Member(member, typename, _dims(dims, slots[:index], cls, source))
        for index, (member, typename, dims) in enumerate(zip(slots, typenames, dimensions, strict=True))
    )
    constants = _constants(cls, set(slots))
    # The same names a .lcm file may not use: our codecs generate a class from this definition.
    problems = [
        name_problem(name, "a struct name", attribute=False),
        *(name_problem(member.name, "a member name", attribute=True) for member in members),
        *(name_problem(constant.name, "a constant name", attribute=True) for constant in constants),
        *(constant_problem(c.type_name, c.value, c.text) for c in constants if c.type_name == "double"),
    ]
    problem = next((problem for problem in problems if problem is not None), None)
    if problem is not None:
        raise SchemaError(source, 0, f"{cls.__name__}: {problem}")
    return StructDef(package, name, members, constants, source, 0)


def _full_name(cls: Any) -> tuple[str, str]:
    """(package, name): lcm-gen writes type `a.b.name` as class `name` in module `a.b.name`."""
    module: str = cls.__module__
    name: str = cls.__name__
    if module == name:
        return "", name
    if module.endswith("." + name):
        return module[: -len(name) - 1], name
    return module, name


def _dims(dims: object, earlier: list[str], cls: Any, source: str) -> tuple[Dimension, ...]:
    if dims is None:
        return ()
    if not isinstance(dims, list | tuple):
        raise SchemaError(source, 0, f"{cls.__name__}: a dimension list is {dims!r}")
    result: list[Dimension] = []
    for size in dims:
        if isinstance(size, int) and not isinstance(size, bool) and size > 0:
            result.append(Dimension(str(size), is_variable=False))
        elif isinstance(size, str) and size in earlier:
            result.append(Dimension(size, is_variable=True))
        else:
            raise SchemaError(
                source, 0, f"{cls.__name__}: array size {size!r} is neither positive nor an earlier member"
            )
    return tuple(result)


def _constants(cls: Any, members: set[str]) -> tuple[Constant, ...]:
    constants: list[Constant] = []
    for name, value in vars(cls).items():
        if name.startswith("_") or name in members or isinstance(value, bool):
            continue
        if isinstance(value, int):
            low, high = INTEGER_RANGES["int32_t"]
            type_name = "int32_t" if low <= value <= high else "int64_t"
            constants.append(Constant(name, type_name, value, str(value)))
        elif isinstance(value, float):
            constants.append(Constant(name, "double", value, repr(value)))
    return tuple(constants)


def _import_class(full_name: str, parent: Any, source: str) -> Any:
    """The class of type `full_name`: from the parent's module namespace, else by importing it."""
    short = full_name.rsplit(".", 1)[-1]
    parent_module = inspect.getmodule(parent)
    candidates: list[ModuleType | None] = [parent_module]
    for module_name in (full_name, full_name.rsplit(".", 1)[0] if "." in full_name else ""):
        if module_name:
            try:
                candidates.append(importlib.import_module(module_name))
            except Exception:  # noqa: BLE001, S112  (try the next place it may live)
                continue
    for module in candidates:
        value = getattr(module, short, None) if module is not None else None
        if is_lcm_class(value) and _dotted(value) == full_name:
            return value
    raise SchemaError(source, 0, f"{parent.__name__}: cannot import member type {full_name}")


def _dotted(cls: Any) -> str:
    package, name = _full_name(cls)
    return f"{package}.{name}" if package else name
