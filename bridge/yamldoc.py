"""YAML files validated with pydantic, whose errors name the file, line and key.

Both the mapping tables and the router's config are YAML; a mistake in either should read like
a compiler error (`mappings/ros.yaml:12: shapes.box.type: unknown type 'CUBE'`), not a stack trace.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from bridge.errors import ConfigError

KeyPath = tuple[str | int, ...]
Model = TypeVar("Model", bound=BaseModel)


class YamlDocument:
    """A parsed YAML file that remembers the line of every key and list item."""

    def __init__(self, path: str, text: str) -> None:
        self.path = path
        try:
            root = yaml.compose(text, Loader=yaml.SafeLoader)
            self.data: Any = yaml.safe_load(text)
        except yaml.YAMLError as error:
            mark = getattr(error, "problem_mark", None)
            line = mark.line + 1 if mark is not None else None
            raise ConfigError(path, line, "", f"not valid YAML: {getattr(error, 'problem', error)}") from None
        self.lines: dict[KeyPath, int] = {}
        if root is not None:
            self._index(root, ())

    @classmethod
    def read(cls, path: Path | str) -> YamlDocument:
        try:
            data = Path(path).read_bytes()
        except OSError as error:
            raise ConfigError(str(path), None, "", f"cannot read: {error.strerror}") from None
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as error:  # found by bench/fuzz.py
            line = data.count(b"\n", 0, error.start) + 1
            reason = f"not UTF-8 text: byte {error.start} is {data[error.start]:#04x}"
            raise ConfigError(str(path), line, "", reason) from None
        return cls(str(path), text)

    def _index(self, node: yaml.Node, key_path: KeyPath) -> None:
        self.lines[key_path] = node.start_mark.line + 1
        if isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                key = key_node.value
                self._index(value_node, (*key_path, key))
                self.lines[(*key_path, key)] = key_node.start_mark.line + 1  # the key's line, not the value's
        elif isinstance(node, yaml.SequenceNode):
            for index, item in enumerate(node.value):
                self._index(item, (*key_path, index))

    def _file_path(self, loc: tuple[Any, ...]) -> KeyPath:
        """pydantic's error location without its type tags (`float`, `list[...]`): the file's keys."""
        path: KeyPath = ()
        for part in loc:
            tag = isinstance(part, str) and (part in _TYPE_TAGS or "[" in part)
            if isinstance(part, str | int) and ((*path, part) in self.lines or not tag):
                path = (*path, part)
        return path

    def line_of(self, key_path: KeyPath) -> int | None:
        """The line of the deepest part of `key_path` the file has."""
        for end in range(len(key_path), -1, -1):
            line = self.lines.get(tuple(key_path[:end]))
            if line is not None:
                return line
        return None

    def error(self, key_path: KeyPath, reason: str) -> ConfigError:
        key = ".".join(str(part) for part in key_path)
        return ConfigError(self.path, self.line_of(key_path), key, reason)

    def validate(self, model: type[Model], context: dict[str, Any] | None = None) -> Model:
        """The document as `model`; the first validation error becomes a `ConfigError`."""
        try:
            return model.model_validate(self.data, context=context)
        except ValidationError as error:
            raise self.validation_error(error) from None

    def validation_error(self, error: ValidationError, at: KeyPath = ()) -> ConfigError:
        """The first error of validating the part of the document at `at`, as a `ConfigError`."""
        first = error.errors()[0]
        return self.error(self._file_path((*at, *first["loc"])), _reason(first))


_TYPE_TAGS = {"float", "int", "str", "bool", "none", "dict", "list"}  # pydantic's union branch names


def _reason(detail: Any) -> str:
    message = str(detail["msg"])
    return message.removeprefix("Value error, ")
