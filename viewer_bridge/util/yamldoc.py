"""YAML files validated with pydantic, whose errors name the file, line and key.

Both the mapping tables and the router's config are YAML; a mistake in either should read like
a compiler error (`mappings/ros.yaml:12: shapes.box.type: unknown type 'CUBE'`), not a stack trace.
"""

from __future__ import annotations

import difflib
import typing
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from viewer_bridge.errors import ConfigError

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
            raise self.validation_error(error, model=model) from None

    def validation_error(
        self, error: ValidationError, at: KeyPath = (), model: type[BaseModel] | None = None
    ) -> ConfigError:
        """The first error of validating the part of the document at `at` (as `model`), as a
        `ConfigError`. An unknown key comes first, since it often explains a missing one (a
        misspelt `translater:`); it is named, with the keys that are known there."""
        errors = error.errors()
        unknown = [detail for detail in errors if detail["type"] == "extra_forbidden"]
        if not unknown:
            return self.error(self._file_path((*at, *errors[0]["loc"])), _reason(errors[0]))
        loc = unknown[0]["loc"]
        parent, key = loc[:-1], loc[-1]
        missing = [str(d["loc"][-1]) for d in errors if d["type"] == "missing" and d["loc"][:-1] == parent]
        known = _fields_at(model, parent) if model is not None else []
        reason = f"unknown key {key!r}"
        guess = difflib.get_close_matches(str(key), missing or known, n=1)
        if guess:
            reason += f" (did you mean {guess[0]!r}?)"
        if known:
            reason += f"; known keys: {', '.join(known)}"
        return self.error(self._file_path((*at, *loc)), reason)


_TYPE_TAGS = {"float", "int", "str", "bool", "none", "dict", "list"}  # pydantic's union branch names


def _fields_at(model: type[BaseModel], loc: tuple[Any, ...]) -> list[str]:
    """The field names of the model found at `loc` inside `model` (through lists and dicts), or []."""
    annotation: Any = model
    for part in loc:
        if isinstance(part, str) and isinstance(annotation, type) and issubclass(annotation, BaseModel):
            field = next((f for name, f in annotation.model_fields.items() if part in (name, f.alias)), None)
            if field is None:
                return []
            annotation = field.annotation
        else:  # an item of a list, or a value of a dict
            arguments = [arg for arg in typing.get_args(annotation) if arg is not type(None)]
            if not arguments:
                return []
            annotation = arguments[-1]
    while typing.get_args(annotation) and not isinstance(annotation, type):  # X | None
        annotation = next(arg for arg in typing.get_args(annotation) if arg is not type(None))
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [field.alias or name for name, field in annotation.model_fields.items()]  # as written
    return []


def _reason(detail: Any) -> str:
    message = str(detail["msg"])
    return message.removeprefix("Value error, ")
