"""The layers of docs/ARCHITECTURE.md, held against the imports of `viewer_bridge/`.

Every module of the package has a layer (a folder gives its modules one); a module may import
only from its own layer or below, with no import circle. Importing `a.b.c` runs `a/__init__.py`
and `a/b/__init__.py` first, so those count as imported too; every `__init__.py` below the root
holds only a docstring, so a folder costs nothing to enter (such a package is on the ground floor).
The same holds when the code runs: a module imported in a fresh interpreter loads no project
module above its layer, lazy imports at import time included. Transports use format code only
through a format's `schema` module, and a translator family imports no other family.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from functools import cache
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
    "viewer_bridge.util.registry": 1,
    "viewer_bridge.util.resources": 1,
    "viewer_bridge.util.words": 1,
    "viewer_bridge.model.sim_time": 1,
    "viewer_bridge.util.lru": 1,
    "viewer_bridge.router.status": 1,
    "viewer_bridge.transports.command_policy": 1,  # the allow-list: patterns over ROS and LCM names
    "viewer_bridge.transports.ros_names": 1,  # ROS names' rules: strings and errors alone (the allow-list maps with them)
    "viewer_bridge.cli": 1,
    "viewer_bridge.ros_build.messages": 1,
    # 2
    "viewer_bridge.model.scene": 2,
    "viewer_bridge.model.pose_math": 2,
    "viewer_bridge.lcmcodec": 2,
    "viewer_bridge.util.yamldoc": 2,
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
    "viewer_bridge.formats.mappings": 4,  # the tables of mappings/, read into the scene model's terms
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
    "viewer_bridge.config.options": 8,
    "viewer_bridge.examples": 8,
    "viewer_bridge.cli.example": 8,
    # 9
    "viewer_bridge.router": 9,
    "viewer_bridge.cli.run": 9,
    "viewer_bridge.cli.play": 9,
    "viewer_bridge.cli.layout": 9,
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
    if module != "viewer_bridge" and holds_only_a_docstring(module):
        return 1  # a folder's `__init__`: importing it loads nothing
    prefix = max((name for name in LAYERS if module == name or module.startswith(name + ".")), key=len)
    return LAYERS[prefix]


@cache
def holds_only_a_docstring(package: str) -> bool:
    init = PACKAGE.parent.joinpath(*package.split("."), "__init__.py")
    if not init.exists():
        return False
    body = ast.parse(init.read_text(), str(init)).body
    return len(body) == 1 and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)


def with_parents(modules: set[str]) -> set[str]:
    """`modules` and every package above each: importing `a.b.c` imports `a` and `a.b` first."""
    return {".".join(name.split(".")[:end]) for name in modules for end in range(1, name.count(".") + 2)}


def imports(path: Path) -> set[str]:
    """The `bridge` modules a file imports, at any depth of its code (lazy imports count too), with
    the packages above them and above the file itself."""
    found: set[str] = {module_name(path)}
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # `from viewer_bridge.formats import ros` names a module; `from viewer_bridge.model.scene import Scene` a name.
            found |= {f"{node.module}.{alias.name}" if _is_module(f"{node.module}.{alias.name}") else node.module
                      for alias in node.names}  # fmt: skip
    found = with_parents(found) - {module_name(path)}
    return {name for name in found if name == "viewer_bridge" or name.startswith("viewer_bridge.")}


def _is_module(name: str) -> bool:
    path = PACKAGE.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


GRAPH = {module_name(path): imports(path) for path in sorted(PACKAGE.rglob("*.py"))}


def test_every_init_below_the_root_holds_only_a_docstring() -> None:
    packages = sorted(module_name(path) for path in PACKAGE.rglob("__init__.py") if path.parent != PACKAGE)
    assert len(packages) > 10, packages  # the check would pass on no package at all
    assert [package for package in packages if not holds_only_a_docstring(package)] == []


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


def folder_of(module: str) -> str:
    """The folder (or top-level module) of `viewer_bridge/` that `module` lives in."""
    return ".".join(module.split(".")[:2])


def folder_graph() -> dict[str, set[str]]:
    """Folder -> the other folders its modules import: the house drawn a folder a room."""
    graph: dict[str, set[str]] = {}
    for module, names in GRAPH.items():
        if module == "viewer_bridge":
            continue  # the facade is the top: it may name any folder
        targets = {
            folder_of(name) for name in names if name != "viewer_bridge" and not holds_only_a_docstring(name)
        }
        graph.setdefault(folder_of(module), set()).update(targets - {folder_of(module)})
    return graph


def test_folders_stack_as_floors() -> None:
    """Folder by folder the imports form no circle, so every folder stands on one floor above all
    it imports: a reader climbs the package from `errors` to `cli` without ever going back down."""
    graph = folder_graph()
    assert len(graph) > 10 and any(graph.values()), graph
    floors: dict[str, int] = {}

    def floor(folder: str, path: tuple[str, ...]) -> int:
        if folder in path:
            raise AssertionError(
                "folders import each other: " + " -> ".join((*path[path.index(folder) :], folder))
            )
        if folder not in floors:
            floors[folder] = 1 + max(
                (floor(below, (*path, folder)) for below in graph.get(folder, ())), default=0
            )
        return floors[folder]

    for folder in sorted(graph):
        floor(folder, ())
    climb = ["errors", "util", "lcmcodec", "formats", "transports", "translators", "config", "router", "cli"]
    assert [floors[f"viewer_bridge.{folder}"] for folder in climb] == sorted(
        {floors[f"viewer_bridge.{f}"] for f in climb}
    ), floors


def test_transports_use_format_code_only_through_schema_modules() -> None:
    used = {(module, name) for module, names in GRAPH.items() if module.startswith("viewer_bridge.transports")
            for name in names if name.startswith("viewer_bridge.formats") and not holds_only_a_docstring(name)}  # fmt: skip
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


# One interpreter per module, forked from a parent that has loaded the heavy third-party
# libraries the package uses (and no project module): a fresh interpreter as far as the project
# goes, at a fraction of the cost of starting one per module. Run as `python -c FORKS modules workers`.
FORKS = """
import importlib, json, os, sys
for library in ("numpy", "pydantic", "yaml", "orjson", "google.protobuf.message", "PIL.Image",
                "rosbags.typesys", "rosbags.serde", "lcm", "rerun", "foxglove", "mcap.writer"):
    try:
        importlib.import_module(library)
    except ImportError:
        pass
assert not [name for name in sys.modules if name.split(".")[0] == "viewer_bridge"]
modules, workers = json.loads(sys.argv[1]), int(sys.argv[2])
loaded, running = {}, {}

def collect():
    pid, _ = os.wait()
    module, reader = running.pop(pid)
    with os.fdopen(reader) as pipe:
        loaded[module] = json.loads(pipe.read())

for module in modules:
    while len(running) >= workers:
        collect()
    reader, writer = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(reader)
        try:
            importlib.import_module(module)
            result = sorted(name for name in sys.modules if name.split(".")[0] == "viewer_bridge")
        except BaseException as error:
            result = {"error": repr(error)}
        os.write(writer, json.dumps(result).encode())
        os._exit(0)
    os.close(writer)
    running[pid] = (module, reader)
while running:
    collect()
print(json.dumps(loaded))
"""


def loaded_at_import() -> dict[str, list[str] | dict[str, str]]:
    """Per module (but the `__main__`s, which run), the project modules importing it loads."""
    modules = [module for module in sorted(GRAPH) if not module.endswith("__main__")]
    result = subprocess.run([sys.executable, "-c", FORKS, json.dumps(modules), "3"],
                            capture_output=True, text=True, check=True, timeout=600)  # fmt: skip
    loaded: dict[str, list[str] | dict[str, str]] = json.loads(result.stdout)
    return loaded


def test_importing_a_module_loads_nothing_above_its_layer() -> None:
    loaded = loaded_at_import()
    assert len(loaded) == len(GRAPH) - 2, sorted(set(GRAPH) - set(loaded))  # all but the two __main__
    failed = {module: names for module, names in loaded.items() if isinstance(names, dict)}
    assert not failed, failed
    above = {module: {name: layer(name) for name in names if layer(name) > layer(module)}
             for module, names in loaded.items()}  # fmt: skip
    assert {module: names for module, names in above.items() if names} == {}
    # The check bites: a module high up loads much of the package below it.
    assert len(loaded["viewer_bridge.cli.main"]) > 30
