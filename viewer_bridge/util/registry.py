"""Named extension points: transports and translators, built in or installed as plugins.

A `Registry` maps a name (the word a config uses) to a class. Built-in entries are given as
`"module:attribute"` strings and imported only when first asked for, so a config that never
names the ROS 2 transport never imports rclpy. Plugins are Python entry points in the
registry's group, e.g. in a plugin package's `pyproject.toml`:

    [project.entry-points."viewer_bridge.transports"]
    memory = "my_plugin:MemoryTransport"

A plugin cannot replace a built-in name: that would change what an existing config means.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from importlib.metadata import entry_points
from typing import Generic, TypeVar, cast

from viewer_bridge.errors import PluginError, UnknownName
from viewer_bridge.util.extras import missing

Entry = TypeVar("Entry")


class Registry(Generic[Entry]):
    """Classes by name: built-ins (imported lazily) and the entry points of one group."""

    def __init__(self, kind: str, group: str, builtins: Mapping[str, str], base: type) -> None:
        self.kind = kind  # "transport", "translator": for messages
        self.group = group
        self._base = base
        self._builtins = dict(builtins)
        self._loaded: dict[str, type[Entry]] = {}

    def names(self) -> list[str]:
        """Every name a config may use: the built-ins, then the plugins'."""
        plugins = [point.name for point in entry_points(group=self.group) if point.name not in self._builtins]
        return [*self._builtins, *sorted(set(plugins))]

    def get(self, name: str) -> type[Entry]:
        """The class registered as `name`; `UnknownName` names the known ones."""
        entry = self._loaded.get(name)
        if entry is None:
            entry = self._loaded[name] = self._load(name)
        return entry

    def __getitem__(self, name: str) -> type[Entry]:
        return self.get(name)

    def _load(self, name: str) -> type[Entry]:
        if name in self._builtins:
            module, _, attribute = self._builtins[name].partition(":")
            try:
                loaded = getattr(importlib.import_module(module), attribute)
            except ImportError as error:  # a built-in whose optional dependency is not installed
                raise missing(error, f"the {self.kind} {name}") from None
        else:
            points = [point for point in entry_points(group=self.group) if point.name == name]
            if not points:
                raise UnknownName(self.kind, name, self.names())
            loaded = points[0].load()
        if not (isinstance(loaded, type) and issubclass(loaded, self._base)):
            raise PluginError(
                f"{self.kind} {name!r} ({self.group}) is not a subclass of {self._base.__name__}"
            )
        return cast("type[Entry]", loaded)
