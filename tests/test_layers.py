"""The layers of docs/ARCHITECTURE.md, held against the imports of `bridge/`.

Every module of the package has a layer (a folder gives its modules one); a module may import
only from its own layer or below, with no import circle. Transports use format code only
through a format's `schema` module, and a translator family imports no other family.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "viewer_bridge"

# The floors of docs/ARCHITECTURE.md, from the ground up: the longest matching prefix decides.
LAYERS: dict[str, int] = {
    # 1
    "viewer_bridge": 1,
    "viewer_bridge.model": 1,
    "viewer_bridge.config": 1,
    "viewer_bridge.render": 1,
    "viewer_bridge.ros_build": 1,
    "viewer_bridge.util": 1,
    "viewer_bridge.util.extras": 1,
    "viewer_bridge.errors": 1,
    "viewer_bridge.payload": 1,
    "viewer_bridge.config.registry": 1,
    "viewer_bridge.config.resources": 1,
    "viewer_bridge.model.sim_time": 1,
    "viewer_bridge.util.lru": 1,
    "viewer_bridge.router.status": 1,
    "viewer_bridge.config.commands": 1,
    "viewer_bridge.cli": 1,
    "viewer_bridge.ros_build.messages": 1,
    # 2
    "viewer_bridge.model.scene": 2,
    "viewer_bridge.model.pose_math": 2,
    "viewer_bridge.lcmcodec": 2,
    "viewer_bridge.config.yamldoc": 2,
    "viewer_bridge.cli.arguments": 2,
    "viewer_bridge.cli.lcm_types": 2,
    "viewer_bridge.cli.ros_interfaces": 2,
    "viewer_bridge.lcmcodec.from_ros": 2,
    "viewer_bridge.lcmcodec.ros_cdr": 2,
    "viewer_bridge.ros_build.interfaces": 2,
    "viewer_bridge.ros_build.packages": 2,
    "viewer_bridge.ros_build.install": 2,
    "viewer_bridge.ros_build.background": 2,
    "viewer_bridge.transports.lcm_url": 2,
    "viewer_bridge.shared": 2,
    # 3
    "viewer_bridge.model.lowering": 3,
    "viewer_bridge.model.contact": 3,
    "viewer_bridge.model.image": 3,
    "viewer_bridge.model.skipped": 3,
    # 4
    "viewer_bridge.config.mappings": 4,
    "viewer_bridge.cli.mappings": 4,
    # 5
    "viewer_bridge.formats": 5,
    # 6
    "viewer_bridge.transports": 6,
    "viewer_bridge.render.renderer": 6,
    "viewer_bridge.convert": 6,
    "viewer_bridge.cli.bag_to_lcm": 6,
    "viewer_bridge.cli.play_keys": 6,
    "viewer_bridge.streams": 6,
    "viewer_bridge.typestore": 6,
    # 7
    "viewer_bridge.translators": 7,
    "viewer_bridge.cli.dump": 7,
    "viewer_bridge.cli.dump_command": 7,
    "viewer_bridge.cli.demo": 7,
    "viewer_bridge.cli.serve_render": 7,
    "viewer_bridge.cli.snapshot": 7,
    "viewer_bridge.render.snapshot": 7,
    "viewer_bridge.examples.demo": 7,
    "viewer_bridge.render.server": 7,
    # 8
    "viewer_bridge.config.bridge": 8,
    "viewer_bridge.examples": 8,
    "viewer_bridge.cli.example": 8,
    # 9
    "viewer_bridge.router": 9,
    "viewer_bridge.cli.run": 9,
    "viewer_bridge.cli.play": 9,
    # 10
    "viewer_bridge.cli.log_convert": 10,
    "viewer_bridge.cli.bag_convert": 10,
    "viewer_bridge.cli.convert": 10,
    # 11
    "viewer_bridge.cli.main": 11,
    "viewer_bridge.cli.__main__": 11,
    "viewer_bridge.__main__": 11,
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
            # `from viewer_bridge.formats import ros` names a module; `from viewer_bridge.model.scene import Scene` a name.
            found |= {f"{node.module}.{alias.name}" if _is_module(f"{node.module}.{alias.name}") else node.module
                      for alias in node.names}  # fmt: skip
    return {name for name in found if name == "viewer_bridge" or name.startswith("viewer_bridge.")}


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
    used = {(module, name) for module, names in GRAPH.items() if module.startswith("viewer_bridge.transports")
            for name in names if name.startswith("viewer_bridge.formats")}  # fmt: skip
    assert used, "no transport names a schema: the check would pass on anything"
    assert all(name.endswith(".schema") for _, name in used), sorted(used)


def test_translator_families_do_not_import_each_other() -> None:
    for module, names in GRAPH.items():
        if not module.startswith("viewer_bridge.translators."):
            continue
        families = {name for name in names if name.startswith("viewer_bridge.translators.")
                    and name.rpartition(".")[2] not in TRANSLATOR_COMMONS and name != module}  # fmt: skip
        assert not families, f"{module} imports the translator families {families}"


def test_the_layer_table_knows_every_module() -> None:
    unknown = [module for module in GRAPH if not any(
        module == name or module.startswith(name + ".") for name in LAYERS if name != "viewer_bridge")]  # fmt: skip
    assert unknown in ([], ["viewer_bridge"]), f"modules without a layer in LAYERS: {unknown}"
