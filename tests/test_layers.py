"""The layers of docs/ARCHITECTURE.md, held against the imports of `bridge/`.

Every module of the package has a layer (a folder gives its modules one); a module may import
only from its own layer or below, with no import circle. Transports use format code only
through a format's `schema` module, and a translator family imports no other family.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "bridge"

# The floors of docs/ARCHITECTURE.md, from the ground up: the longest matching prefix decides.
LAYERS: dict[str, int] = {
    "bridge": 1,  # the package's __init__ (a docstring and the version)
    "bridge.errors": 1, "bridge.registry": 1, "bridge.resources": 1, "bridge.sim_time": 1,
    "bridge.lru": 1, "bridge.status": 1,
    "bridge.scene": 2, "bridge.lcmcodec": 2, "bridge.yamldoc": 2, "bridge.arguments": 2,
    "bridge.ros_interfaces": 2,
    "bridge.lowering": 3, "bridge.contact": 3, "bridge.image": 3, "bridge.skipped": 3,
    "bridge.mappings": 4,
    "bridge.formats": 5,
    "bridge.transports": 6, "bridge.render": 6,
    "bridge.translators": 7, "bridge.dump": 7, "bridge.snapshot": 7, "bridge.demo": 7,
    "bridge.render_server": 7,
    "bridge.config": 8,
    "bridge.router": 9,
    "bridge.convert": 10,
    "bridge.cli": 11, "bridge.__main__": 11,
}  # fmt: skip

# What every translator family may share (translators/ modules that are no family).
TRANSLATOR_COMMONS = {"base", "types", "options", "drake_stream", "load_cache", "__init__"}


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer(module: str) -> int:
    prefix = max((name for name in LAYERS if module == name or module.startswith(name + ".")), key=len)
    return LAYERS[prefix]


def imports(path: Path) -> set[str]:
    """The `bridge` modules a file imports, at any depth of its code (lazy imports count too)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # `from bridge.formats import ros` names a module; `from bridge.scene import Scene` a name.
            found |= {f"{node.module}.{alias.name}" if _is_module(f"{node.module}.{alias.name}") else node.module
                      for alias in node.names}  # fmt: skip
    return {name for name in found if name == "bridge" or name.startswith("bridge.")}


def _is_module(name: str) -> bool:
    path = PACKAGE.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


GRAPH = {module_name(path): imports(path) for path in sorted(PACKAGE.rglob("*.py"))}


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_a_module_imports_only_from_its_layer_or_below(module: str) -> None:
    above = {name: layer(name) for name in GRAPH[module] if layer(name) > layer(module)}
    assert not above, f"{module} (layer {layer(module)}) imports from above: {above}"


def test_no_import_circle() -> None:
    done: set[str] = set()

    def visit(module: str, path: tuple[str, ...]) -> None:
        if module in path:
            raise AssertionError(" -> ".join((*path[path.index(module) :], module)))
        if module in done or module not in GRAPH:
            return
        for imported in sorted(GRAPH[module]):
            visit(imported, (*path, module))
        done.add(module)

    for module in sorted(GRAPH):
        visit(module, ())


def test_transports_use_format_code_only_through_schema_modules() -> None:
    used = {(module, name) for module, names in GRAPH.items() if module.startswith("bridge.transports")
            for name in names if name.startswith("bridge.formats")}  # fmt: skip
    assert used, "no transport names a schema: the check would pass on anything"
    assert all(name.endswith(".schema") for _, name in used), sorted(used)


def test_translator_families_do_not_import_each_other() -> None:
    for module, names in GRAPH.items():
        if not module.startswith("bridge.translators."):
            continue
        families = {name for name in names if name.startswith("bridge.translators.")
                    and name.rpartition(".")[2] not in TRANSLATOR_COMMONS and name != module}  # fmt: skip
        assert not families, f"{module} imports the translator families {families}"


def test_the_layer_table_knows_every_module() -> None:
    unknown = [module for module in GRAPH if not any(
        module == name or module.startswith(name + ".") for name in LAYERS if name != "bridge")]  # fmt: skip
    assert unknown in ([], ["bridge"]), f"modules without a layer in LAYERS: {unknown}"
