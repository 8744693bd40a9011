"""The package's face: the few modules users import carry an `__all__`, no other module does,
and every exception class the package defines lives in `viewer_bridge/errors.py` under
`BridgeError`, listed in its `__all__`. The public paths raise no bare `ValueError`, `KeyError`,
`RuntimeError` or `TypeError`: a caller catches one typed error (which mixes in the built-in
where callers expect it)."""

from __future__ import annotations

import ast
import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from viewer_bridge import errors

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "viewer_bridge"

# The modules users import: the facade, streams, errors, the type store, what a plugin author
# subclasses, the scene model and extras (both in the API reference), and the modules the user
# guides in docs/ import from. Only these carry an `__all__`.
PUBLIC = {
    "viewer_bridge",
    "viewer_bridge.convert",
    "viewer_bridge.streams",
    "viewer_bridge.errors",
    "viewer_bridge.typestore",
    "viewer_bridge.transports.base",
    "viewer_bridge.translators.base",
    "viewer_bridge.model.scene",
    "viewer_bridge.util.extras",
    # named by docs/library.md, director.md and lcm-types.md
    "viewer_bridge.transports.lcm",
    "viewer_bridge.lcmcodec.codecs",
    "viewer_bridge.lcmcodec.ros_cdr",
    "viewer_bridge.cli.bag_to_lcm",
    "viewer_bridge.formats.ros.shapes",
    "viewer_bridge.formats.ros.poses",
    "viewer_bridge.formats.ros.messages",
    "viewer_bridge.formats.ros.message_types",
    "viewer_bridge.formats.ros.markers",
    "viewer_bridge.formats.ign.schema",
    "viewer_bridge.formats.ign.poses",
    "viewer_bridge.formats.ign.model",
    "viewer_bridge.formats.drake.load",
    "viewer_bridge.formats.drake.draw",
    "viewer_bridge.formats.tree_viewer.tree",
    "viewer_bridge.formats.tree_viewer.requests",
    "viewer_bridge.formats.tree_viewer.envelope",
    "viewer_bridge.examples.demo",
}

# The public paths: what a caller of the library or a plugin meets first, and the config's loading
# (the settings models' validators raise a typed error that is a ValueError too). The translator
# base's `TypeError` and `RuntimeError` are a caller's or a translator's bugs, not bad input.
NO_BARE_RAISES = ["viewer_bridge", "viewer_bridge.convert", "viewer_bridge.streams", "viewer_bridge.errors",
                  "viewer_bridge.typestore", "viewer_bridge.transports.base", "viewer_bridge.config.bridge",
                  "viewer_bridge.translators.options", "viewer_bridge.transports.command_policy",
                  "viewer_bridge.transports.foxglove", "viewer_bridge.transports.zenoh.transport",
                  "viewer_bridge.transports.zenoh.session"]  # fmt: skip
BARE = {"ValueError", "KeyError", "RuntimeError", "TypeError"}


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def modules() -> dict[str, ast.Module]:
    return {module_name(path): ast.parse(path.read_text()) for path in sorted(PACKAGE.rglob("*.py"))}


def declares_all(tree: ast.Module) -> bool:
    return any(
        isinstance(node, ast.Assign | ast.AnnAssign)
        and any(isinstance(target, ast.Name) and target.id == "__all__"
                for target in (node.targets if isinstance(node, ast.Assign) else [node.target]))
        for node in tree.body
    )  # fmt: skip


def test_only_the_public_modules_declare_all() -> None:
    with_all = {name for name, tree in modules().items() if declares_all(tree)}
    assert with_all == PUBLIC


def test_declares_all_sees_every_form() -> None:
    assert declares_all(ast.parse("__all__ = ['a']")) and declares_all(ast.parse("__all__: list[str] = []"))
    assert not declares_all(ast.parse("def f():\n    __all__ = ['a']\n"))


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_every_exported_name_is_there(name: str) -> None:
    module = importlib.import_module(name)
    assert [exported for exported in module.__all__ if not hasattr(module, exported)] == []
    assert len(set(module.__all__)) == len(module.__all__)


# Every module imported in a fresh interpreter (a module's import may not disturb the test's),
# and the exception classes each defines listed.
EXCEPTIONS = """
import importlib, json, sys
found = {}
for name in json.loads(sys.argv[1]):
    module = importlib.import_module(name)
    found[name] = [value.__name__ for value in vars(module).values()
                   if isinstance(value, type) and issubclass(value, BaseException) and value.__module__ == name]
print(json.dumps(found))
"""


def test_every_exception_class_is_in_errors_under_bridge_error() -> None:
    names = [name for name in modules() if not name.endswith("__main__")]
    done = subprocess.run([sys.executable, "-c", EXCEPTIONS, json.dumps(names)], capture_output=True, text=True,
                          check=True, cwd=ROOT, timeout=600)  # fmt: skip
    found = json.loads(done.stdout)
    assert sorted(found) == sorted(names)  # every module imported
    assert {
        name: classes for name, classes in found.items() if classes and name != "viewer_bridge.errors"
    } == {}
    assert len(found["viewer_bridge.errors"]) > 30
    assert [
        name
        for name in found["viewer_bridge.errors"]
        if not issubclass(getattr(errors, name), errors.BridgeError)
    ] == []
    assert sorted(set(found["viewer_bridge.errors"]) - set(errors.__all__)) == []


def bare_raises(tree: ast.Module) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and node.exc is not None:
            raised = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            if isinstance(raised, ast.Name) and raised.id in BARE:
                found.append(f"line {node.lineno}: {raised.id}")
    return found


def test_the_public_paths_raise_no_bare_built_in() -> None:
    trees = modules()
    assert {name: bare_raises(trees[name]) for name in NO_BARE_RAISES if bare_raises(trees[name])} == {}


def test_bare_raises_finds_them() -> None:
    assert bare_raises(ast.parse("raise KeyError(name)\nraise ValueError\nraise DecodeError('a')")) == [
        "line 1: KeyError",
        "line 2: ValueError",
    ]


def test_the_mixed_in_built_ins_still_catch() -> None:
    """Callers that caught the built-in before the typed error still catch it, and the message reads
    as written (KeyError's own `str` would quote it)."""
    unknown = errors.UnknownName("LCM or ROS 2 type", "lab.nothing_t", ["lab.something_t"])
    assert isinstance(unknown, KeyError) and isinstance(unknown, errors.BridgeError)
    assert (
        str(unknown)
        == "unknown LCM or ROS 2 type 'lab.nothing_t' (did you mean 'lab.something_t'? known: lab.something_t)"
    )
    many = errors.UnknownName("type", "a_t", [f"t{index}" for index in range(200)])
    assert str(many) == "unknown type 'a_t' (200 known)" and len(many.known) == 200
    for error_class in (errors.InvalidName, errors.InvalidSetting, errors.NameRefused, errors.InflateError):
        assert issubclass(error_class, ValueError) and issubclass(error_class, errors.BridgeError)
