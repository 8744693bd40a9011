"""The translation tables in `mappings/`: how each scene shape is written in each target format.

A table file (`mappings/<format>.yaml`) holds one or more tables. A table names the target
message, its shape type codes, and for every shape kind of the scene model (`scene.SHAPE_KINDS`)
one rule, either

* direct: `{type: CYLINDER, fields: {dimensions: [length, radius]}}`: the target type (or, with
  `message`, another message type to write instead) and, per target field, terms read from the
  shape (`radius`, `2 * radius`, `size.x`, a literal `0`), or
* lowered: `{as: capsule_parts}`: the shape is first rewritten by a named function in
  `viewer_bridge.model.lowering` into shapes the table has direct rules for, or
* unsupported: `{unsupported: "reason"}`: the target cannot express it; writing one raises a
  `SceneError` with the reason (counted by the router), never a silent drop.

A rule may also name an `encoder`: a small function of the format module that fills the fields a
table cannot express (a mesh's vertices). Direct rules whose terms cover every parameter of the
shape are invertible, which is how the reverse directions (Model -> scene, tree JSON -> scene,
Drake load -> scene) read shapes back. Tables are validated when loaded: a mistake is a
`ConfigError` with file, line and key.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from functools import cache, cached_property
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from viewer_bridge.errors import SceneError
from viewer_bridge.model.lowering import LOWERINGS
from viewer_bridge.model.scene import SHAPE_KINDS, Pose, Shape, shape_kind
from viewer_bridge.util.resources import data_dir
from viewer_bridge.util.yamldoc import KeyPath, YamlDocument

# A function that writes what a table's terms cannot (a mesh's vertices, say): the fields it sets.
Encoder = Callable[..., dict[str, Any]]

# fullmatch
_TERM = re.compile(r"(?:(?P<factor>[0-9]+(?:\.[0-9]*)?)\s*\*\s*)?(?P<field>[a-z_]+)(?:\.(?P<axis>[xyz]))?")
_AXES = "xyz"


@dataclass(frozen=True, slots=True)
class Term:
    """One value of a target field: a literal, or `factor * <shape field>[.axis]`."""

    field: str | None = None
    axis: int | None = None
    factor: float = 1.0
    literal: float | None = None

    def expression(self, numeric: bool) -> str:
        """This term as Python source reading a shape bound to `shape`."""
        if self.field is None:
            return repr(self.literal)
        value = f"shape.{self.field}" + (f"[{self.axis}]" if self.axis is not None else "")
        if not numeric:
            return value
        return f"float({value})" if self.factor == 1.0 else f"{self.factor!r} * {value}"

    def __str__(self) -> str:
        if self.field is None:
            return f"{self.literal:g}"
        text = self.field + (f".{_AXES[self.axis]}" if self.axis is not None else "")
        return text if self.factor == 1.0 else f"{self.factor:g} * {text}"


@dataclass(frozen=True, slots=True)
class ShapeRule:
    """How one shape kind is written in one target (see the module docstring)."""

    kind: str
    type: str | None = None
    type_code: Any = None  # an int, or the name itself for formats whose types are names
    lower: str | None = None
    fields: Mapping[str, tuple[Term, ...]] = dataclasses.field(default_factory=dict)
    list_fields: frozenset[str] = frozenset()
    encoder: str | None = None
    message: str | None = None
    unsupported: str | None = None  # why the target cannot express this kind: a SceneError
    note: str = ""
    encode: Encoder | None = dataclasses.field(default=None, repr=False, compare=False)  # `encoder`, bound

    reader: Callable[[Shape], dict[str, Any]] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "reader", _compile_reader(self.fields, self.list_fields))

    def values(self, shape: Shape, *context: Any) -> dict[str, Any]:
        """The target fields this rule sets for `shape`: a value or a list per field, read by
        the table's terms, then what the rule's encoder adds (given `context`, e.g. options)."""
        values = self.reader(shape)
        if self.encode is not None:
            values |= self.encode(shape, *context)
        return values

    @property
    def invertible(self) -> bool:
        """Whether the shape can be rebuilt from the fields (every parameter is read by a term)."""
        if self.lower is not None or self.encoder is not None or self.unsupported is not None:
            return False
        needed = {(item.name, axis) for item in _parameters(self.kind) for axis in _axes_of(self.kind, item)}
        read = {(term.field, term.axis) for terms in self.fields.values() for term in terms if term.field}
        return needed <= read

    def shape_from(self, values: Mapping[str, Any]) -> Shape:
        """The shape whose fields are `values` (the inverse of `values`).

        A field that is absent takes the shape's default when its parameters have one (a mesh's
        scale, a triad's tube). Raises `ValueError` naming the field when a value is missing,
        not a number, or a list is too short.
        """
        parameters = {item.name: _default(item) for item in _parameters(self.kind)}
        for name, terms in self.fields.items():
            if name not in values and all(
                term.field is None or parameters[term.field] is not None for term in terms
            ):
                continue
            given = _given_values(values, name, len(terms) if name in self.list_fields else None, self.kind)
            for index, (term, value) in enumerate(zip(terms, given, strict=False)):
                if term.field is None:
                    # A fixed value the target may only hold as written: anything else would
                    # be a different shape, read back silently wrong.
                    if value != term.literal:
                        where = f"{name}[{index}]" if name in self.list_fields else name
                        raise ValueError(f"{self.kind} needs {where} = {term}, got {value!r}")
                    continue
                parameter = _term_value(term, value, name, self.kind)
                if term.axis is None:
                    parameters[term.field] = parameter
                else:
                    if parameters[term.field] is None:
                        parameters[term.field] = [0.0, 0.0, 0.0]
                    parameters[term.field][term.axis] = parameter
        arguments: dict[str, Any] = {
            key: tuple(value) if isinstance(value, list) else value for key, value in parameters.items()
        }
        return SHAPE_KINDS[self.kind](**arguments)


def _default(item: dataclasses.Field[Any]) -> Any:
    """A parameter's default as `shape_from` fills it in (vectors as lists), or None."""
    if item.default is dataclasses.MISSING:
        return None
    return list(item.default) if isinstance(item.default, tuple) else item.default


def _compile_reader(
    fields: Mapping[str, tuple[Term, ...]], list_fields: frozenset[str]
) -> Callable[[Shape], dict[str, Any]]:
    """A function reading a rule's fields from a shape, compiled once per rule.

    Markers and models are built for every geometry of a load, so the terms become one
    Python expression each (`{"scale": [2.0 * shape.radius, ...]}`) instead of being
    interpreted per shape.
    """
    items = []
    for name, terms in fields.items():
        parts = [term.expression(not _is_text(term)) for term in terms]
        items.append(f"{name!r}: [{', '.join(parts)}]" if name in list_fields else f"{name!r}: {parts[0]}")
    namespace: dict[str, Any] = {}
    exec(f"def read(shape):\n    return {{{', '.join(items)}}}\n", namespace)  # noqa: S102 - our own table terms
    return namespace["read"]  # type: ignore[no-any-return]


def _given_values(values: Mapping[str, Any], name: str, count: int | None, kind: str) -> Sequence[Any]:
    if name not in values:
        raise ValueError(f"{kind} needs {name}, which is missing")
    value = values[name]
    if count is None:
        return [value]
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) < count:
        length = len(value) if isinstance(value, Sequence) and not isinstance(value, str) else "no"
        raise ValueError(f"{kind} needs {count} values in {name}, got {length}")
    return value


def _term_value(term: Term, value: Any, name: str, kind: str) -> Any:
    wanted = next(item.type for item in _parameters(kind) if item.name == term.field)
    if wanted == "bool":
        if isinstance(value, bool):
            return value
        raise ValueError(f"{name} must be true or false, got {value!r}")
    if wanted == "str":
        if isinstance(value, str):
            return value
        raise ValueError(f"{name} must be text, got {value!r}")
    if isinstance(value, str):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return float(value) / term.factor


@dataclass(frozen=True, slots=True)
class Table:
    """One target message's rules, keyed by shape kind."""

    name: str
    target: str
    types: Mapping[str, Any]
    rules: Mapping[str, ShapeRule]
    options: Mapping[str, Any]
    note: str = ""

    def rule_for(self, shape: Shape) -> ShapeRule:
        return self.rules[shape_kind(shape)]

    def expand(self, shape: Shape, pose: Pose | None = None) -> list[tuple[ShapeRule, Shape, Pose]]:
        """The direct rules that write `shape`, after its lowering if the table lowers it.

        A capsule that a table lowers to a cylinder and two spheres expands to three entries,
        each posed in the frame `pose` is expressed in.
        """
        rule = self._supported_rule(shape)
        pose = pose or Pose()
        if rule.lower is None:
            return [(rule, shape, pose)]
        parts = LOWERINGS[rule.lower].function(shape)
        return [entry for part, offset in parts for entry in self.expand(part, pose.compose(offset))]

    def expand_unposed(self, shape: Shape) -> list[tuple[ShapeRule, Shape]]:
        """`expand` without the poses, for messages that carry none (shape_msgs): composing
        them took a quarter of a shape_msgs load."""
        rule = self._supported_rule(shape)
        if rule.lower is None:
            return [(rule, shape)]
        return [
            entry for part, _ in LOWERINGS[rule.lower].function(shape) for entry in self.expand_unposed(part)
        ]

    def _supported_rule(self, shape: Shape) -> ShapeRule:
        rule = self.rule_for(shape)
        if rule.unsupported is not None:
            raise SceneError(f"{self.target} has no {rule.kind}: {rule.unsupported}")
        return rule

    def decode(self, type_code: Any, values: Mapping[str, Any]) -> Shape:
        """The shape written as `type_code` with `values`, by the first invertible rule of that type.

        Raises `ValueError` for a type no invertible rule has, or values that do not fit it.
        """
        for rule in self.rules.values():
            if rule.type_code == type_code and rule.invertible:
                return rule.shape_from(values)
        raise ValueError(f"no shape of {self.target} has type {type_code}")

    def decode_message(self, message: str, values: Mapping[str, Any]) -> Shape:
        """Like `decode`, for the rules that write another message type instead (`message:`)."""
        for rule in self.rules.values():
            if rule.message == message and rule.type_code is None and rule.invertible:
                return rule.shape_from(values)
        raise ValueError(f"no shape of {self.target} is written as {message}")

    def type_name(self, code: Any) -> str:
        names = [name for name, value in self.types.items() if value == code]
        return names[0] if names else str(code)


# --- loading -------------------------------------------------------------------------------------


class _RuleSpec(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    type: str | None = None
    lower: str | None = Field(None, alias="as")
    fields: dict[str, float | str | list[float | str]] = {}
    encoder: str | None = None
    message: str | None = None
    unsupported: str | None = None
    note: str = ""


class _TableSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")

    target: str
    note: str = ""
    types: dict[str, int] | list[str]  # a list: the type names are the codes (JSON formats)
    shapes: dict[str, _RuleSpec]
    options: dict[str, Any] = {}


class _FileSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")

    format: str
    tables: dict[str, _TableSpec]


def load_tables(document: YamlDocument, encoders: Collection[str] | None = None) -> dict[str, Table]:
    """Validate a table file; `encoders` are the hook names its format module provides.

    With `encoders` None the encoder names are not checked (enough to print the reference).
    """
    spec = document.validate(_FileSpec)
    return {
        name: _table(document, ("tables", name), name, table, encoders) for name, table in spec.tables.items()
    }


@cache
def _document(format_name: str) -> YamlDocument:
    """`mappings/<format_name>.yaml`, parsed once however many readers it has."""
    return YamlDocument.read(data_dir("mappings") / f"{format_name}.yaml")


@cache
def tables(format_name: str) -> dict[str, Table]:
    """The tables of `mappings/<format_name>.yaml` as written, encoders unbound (for the reference,
    and for schemas that take a table's type codes)."""
    return load_tables(_document(format_name))


class FormatTables:
    """A format's tables with its encoders bound to the rules that name them, read on first use.

    A format module holds one, made from the functions that write what a table cannot express
    (`FormatTables("ros", {"mesh": _mesh, ...})`); `TABLES["marker"]` is then a `Table`
    whose rules yield all their values (`rule.values(shape, ...)`), with no dispatch of its own.
    """

    def __init__(self, format_name: str, encoders: Mapping[str, Encoder]) -> None:
        self.format_name = format_name
        self.encoders = dict(encoders)

    @cached_property
    def _tables(self) -> dict[str, Table]:
        return load_tables(_document(self.format_name), self.encoders)

    def __getitem__(self, name: str) -> Table:
        return self._tables[name]


def _table(
    document: YamlDocument, where: KeyPath, name: str, spec: _TableSpec, encoders: Collection[str] | None
) -> Table:
    types: dict[str, Any] = (
        {name: name for name in spec.types} if isinstance(spec.types, list) else spec.types
    )
    rules: dict[str, ShapeRule] = {}
    for kind, rule_spec in spec.shapes.items():
        if kind not in SHAPE_KINDS:
            known = ", ".join(SHAPE_KINDS)
            raise document.error((*where, "shapes", kind), f"unknown shape kind (known: {known})")
        rules[kind] = _rule(document, (*where, "shapes", kind), kind, rule_spec, types, encoders)
    missing = [kind for kind in SHAPE_KINDS if kind not in rules]
    if missing:
        # Every shape must have a way out: a shape a table forgets would be dropped silently.
        raise document.error((*where, "shapes"), f"no rule for {', '.join(missing)}")
    for kind, rule in rules.items():
        if rule.lower is not None:
            for produced in LOWERINGS[rule.lower].produces:
                if rules[produced].lower is not None or rules[produced].unsupported is not None:
                    raise document.error(
                        (*where, "shapes", kind, "as"),
                        f"{rule.lower} makes {produced}, which has no direct rule",
                    )
    return Table(name, spec.target, types, rules, dict(spec.options), spec.note)


def _rule(
    document: YamlDocument,
    where: KeyPath,
    kind: str,
    spec: _RuleSpec,
    types: Mapping[str, Any],
    encoders: Collection[str] | None,
) -> ShapeRule:
    direct = spec.type is not None or spec.message is not None
    if [direct, spec.lower is not None, spec.unsupported is not None].count(True) != 1:
        raise document.error(
            where,
            "give 'type' or 'message' (a direct rule), or 'as' (a lowering), or 'unsupported' (why not)",
        )
    if spec.type is not None and spec.type not in types:
        raise document.error((*where, "type"), f"unknown type {spec.type!r} (known: {', '.join(types)})")
    if spec.lower is not None and spec.lower not in LOWERINGS:
        raise document.error(
            (*where, "as"), f"unknown lowering {spec.lower!r} (known: {', '.join(LOWERINGS)})"
        )
    if spec.encoder is not None and encoders is not None and spec.encoder not in encoders:
        known = ", ".join(encoders) or "none"
        raise document.error((*where, "encoder"), f"unknown encoder {spec.encoder!r} (known: {known})")
    fields: dict[str, tuple[Term, ...]] = {}
    list_fields = set()
    for name, value in spec.fields.items():
        items = value if isinstance(value, list) else [value]
        if isinstance(value, list):
            list_fields.add(name)
        fields[name] = tuple(
            _term(document, (*where, "fields", name, index), kind, item) for index, item in enumerate(items)
        )
    return ShapeRule(
        kind=kind,
        type=spec.type,
        type_code=types[spec.type] if spec.type is not None else None,
        lower=spec.lower,
        fields=fields,
        list_fields=frozenset(list_fields),
        encoder=spec.encoder,
        encode=encoders[spec.encoder] if isinstance(encoders, Mapping) and spec.encoder else None,
        message=spec.message,
        unsupported=spec.unsupported,
        note=spec.note,
    )


def _term(document: YamlDocument, where: KeyPath, kind: str, item: float | str) -> Term:
    if not isinstance(item, str):
        return Term(literal=float(item))
    match = _TERM.fullmatch(item.strip())
    if match is None:
        raise document.error(where, f"{item!r} is not a number, 'field', 'field.x' or 'factor * field'")
    field, axis, factor = match["field"], match["axis"], match["factor"]
    parameters = {parameter.name: parameter for parameter in _parameters(kind)}
    if field not in parameters:
        raise document.error(
            where, f"{kind} has no field {field!r} (it has: {', '.join(parameters) or 'none'})"
        )
    if _is_vector(kind, field) != (axis is not None):
        raise document.error(
            where, f"{kind}.{field} " + ("needs .x/.y/.z" if axis is None else "is not a vector")
        )
    term = Term(field, _AXES.index(axis) if axis else None, float(factor) if factor else 1.0)
    if factor and _is_text(term, kind):
        raise document.error(where, f"{kind}.{field} is not a number and cannot be scaled")
    return term


# --- shape parameters, from the scene's dataclasses ------------------------------------------------


def _parameters(kind: str) -> tuple[dataclasses.Field[Any], ...]:
    """The parameters of a shape kind a term may read (numbers, vectors and text)."""
    return tuple(
        item
        for item in dataclasses.fields(SHAPE_KINDS[kind])
        if item.type in ("float", "Vector3", "str", "bool")
    )


def _is_vector(kind: str, field: str) -> bool:
    return any(
        item.name == field and item.type == "Vector3" for item in dataclasses.fields(SHAPE_KINDS[kind])
    )


def _axes_of(kind: str, item: dataclasses.Field[Any]) -> tuple[int | None, ...]:
    return (0, 1, 2) if _is_vector(kind, item.name) else (None,)


def _is_text(term: Term, kind: str | None = None) -> bool:
    """Whether the term reads a text or flag parameter (passed through, never scaled)."""
    kinds = [kind] if kind else list(SHAPE_KINDS)
    return any(
        item.name == term.field and item.type in ("str", "bool")
        for name in kinds
        for item in dataclasses.fields(SHAPE_KINDS[name])
    )


# --- the reference page ------------------------------------------------------------------------------


def format_names() -> list[str]:
    """The formats that have a table file in mappings/."""
    return sorted(path.stem for path in data_dir("mappings").glob("*.yaml"))


def reference_markdown(format_names: Sequence[str]) -> str:
    """`mappings/REFERENCE.md`: every table as a Markdown table, generated so it never drifts."""
    lines = [
        "# Mapping reference",
        "",
        "Generated from the tables in `mappings/` by `viewer-bridge mappings`; do not edit by hand.",
        "Terms read the scene's shape parameters (SI units, radius not diameter, full box lengths,",
        "ellipsoid semi-axes); `as` names a lowering in `viewer_bridge/model/lowering.py`; an encoder is a small",
        "function of the format module that fills what a table cannot (vertices, file bytes).",
    ]
    for format_name in format_names:
        for name, table in tables(format_name).items():
            lines += ["", f"## {format_name}: {name} (`{table.target}`)", ""]
            if table.note:
                lines += [table.note, ""]
            lines += ["| shape | type | fields | note |", "|---|---|---|---|"]
            for kind, rule in table.rules.items():
                lines.append(f"| {kind} | {_type_cell(rule)} | {_fields_cell(rule)} | {rule.note} |")
            if table.options:
                options = ", ".join(f"`{key}: {value}`" for key, value in table.options.items())
                lines += ["", f"Options: {options}"]
    return "\n".join(lines) + "\n"


def _type_cell(rule: ShapeRule) -> str:
    if rule.unsupported is not None:
        return f"unsupported: {rule.unsupported}"
    if rule.lower is not None:
        produced = ", ".join(LOWERINGS[rule.lower].produces)
        return f"as `{rule.lower}` ({produced})"
    if rule.type is None:
        return f"`{rule.message}`"
    message = f" in `{rule.message}`" if rule.message else ""
    code = "" if rule.type_code == rule.type else f" = {rule.type_code}"
    return f"{rule.type}{code}{message}"


def _fields_cell(rule: ShapeRule) -> str:
    cells = []
    for name, terms in rule.fields.items():
        text = ", ".join(str(term) for term in terms)
        cells.append(f"`{name}` = [{text}]" if name in rule.list_fields else f"`{name}` = {text}")
    if rule.encoder:
        cells.append(f"encoder `{rule.encoder}`")
    return "; ".join(cells)
