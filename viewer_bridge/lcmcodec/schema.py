"""LCM type definitions: parse `.lcm` files and compute their fingerprints.

This module knows what a type *is*; `serde` turns a definition into code that reads and writes it.
The grammar and the fingerprint rules follow the LCM type specification: the base hash covers
each member's name, its type name when primitive, and its dimensions; a compound member adds the
child's hash; the sum is rotated left by one bit.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from viewer_bridge.errors import SchemaError

# Big-endian struct codes and sizes of LCM's primitive types. `string` is primitive too but has
# no fixed size: it is a uint32 length (including the NUL), the UTF-8 bytes, and a NUL.
PRIMITIVE_FORMATS: Mapping[str, tuple[str, int]] = {
    "int8_t": ("b", 1),
    "int16_t": ("h", 2),
    "int32_t": ("i", 4),
    "int64_t": ("q", 8),
    "float": ("f", 4),
    "double": ("d", 8),
    "boolean": ("b", 1),
    "byte": ("B", 1),
}
PRIMITIVE_TYPES = frozenset(PRIMITIVE_FORMATS) | {"string"}
INTEGER_TYPES = frozenset({"int8_t", "int16_t", "int32_t", "int64_t", "byte"})
STRING_MIN_SIZE = 5  # length word + NUL

_MASK64 = (1 << 64) - 1


@dataclass(frozen=True, slots=True)
class Dimension:
    """One array dimension: a literal size, or the name of an earlier integer member."""

    size: str
    is_variable: bool

    @property
    def mode(self) -> int:
        """The dimension mode as the fingerprint counts it (constant 0, variable 1)."""
        return 1 if self.is_variable else 0


@dataclass(frozen=True, slots=True)
class Member:
    """A struct member. `type_name` is a primitive name or a fully qualified struct name."""

    name: str
    type_name: str
    dims: tuple[Dimension, ...]

    @property
    def is_primitive(self) -> bool:
        return self.type_name in PRIMITIVE_TYPES


@dataclass(frozen=True, slots=True)
class Constant:
    """A `const` declaration; it is a class attribute, not part of the wire format."""

    name: str
    type_name: str
    value: int | float


@dataclass(frozen=True, slots=True)
class StructDef:
    """One parsed `struct`, with the file it came from for error messages."""

    package: str
    name: str
    members: tuple[Member, ...]
    constants: tuple[Constant, ...]
    source: str

    @property
    def full_name(self) -> str:
        return f"{self.package}.{self.name}" if self.package else self.name

    def base_hash(self) -> int:
        """The struct's own hash before children are added (unsigned 64-bit)."""
        value = 0x12345678
        for member in self.members:
            value = _hash_string(value, member.name)
            if member.is_primitive:
                value = _hash_string(value, member.type_name)
            value = _hash_byte(value, len(member.dims))
            for dim in member.dims:
                value = _hash_byte(value, dim.mode)
                value = _hash_string(value, dim.size)
        return value & _MASK64


def _to_signed64(value: int) -> int:
    value &= _MASK64
    return value - (1 << 64) if value >> 63 else value


def _hash_byte(value: int, byte: int) -> int:
    # The reference works on a signed 64-bit integer: the right shift is arithmetic.
    return _to_signed64(((value << 8) ^ (value >> 55)) + byte)


def _hash_string(value: int, text: str) -> int:
    value = _hash_byte(value, len(text))
    for char in text.encode("ascii"):
        value = _hash_byte(value, char)
    return value


def fingerprint(struct: StructDef, structs: Mapping[str, StructDef]) -> int:
    """The 64-bit fingerprint written in front of every encoded message of this type."""
    return _recursive_hash(struct, structs, ())


def _recursive_hash(struct: StructDef, structs: Mapping[str, StructDef], parents: tuple[str, ...]) -> int:
    if struct.full_name in parents:
        return 0
    inner = parents + (struct.full_name,)
    value = struct.base_hash()
    for member in struct.members:
        if not member.is_primitive:
            value += _recursive_hash(structs[member.type_name], structs, inner)
    value &= _MASK64
    return ((value << 1) & _MASK64) + (value >> 63)


# --- parsing ---------------------------------------------------------------------------------

_TOKEN = re.compile(
    r"""
    (?P<space>\s+)
  | (?P<line_comment>//[^\n]*)
  | (?P<block_comment>/\*.*?\*/)
  | (?P<number>[-+]?(?:0[xX][0-9a-fA-F]+|\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?))
  | (?P<word>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*)
  | (?P<symbol>[{}\[\];,=])
    """,
    re.VERBOSE | re.DOTALL,
)
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


@dataclass(frozen=True, slots=True)
class _Token:
    text: str
    line: int


def _tokenize(text: str, path: str) -> list[_Token]:
    tokens: list[_Token] = []
    position = 0
    line = 1
    while position < len(text):
        match = _TOKEN.match(text, position)
        if match is None:
            raise SchemaError(path, line, f"unexpected character {text[position]!r}")
        kind = match.lastgroup
        if kind in ("number", "word", "symbol"):
            tokens.append(_Token(match.group(), line))
        line += match.group().count("\n")
        position = match.end()
    return tokens


class _Parser:
    """A recursive-descent parser over the token list of one file."""

    def __init__(self, text: str, path: str) -> None:
        self.path = path
        self.tokens = _tokenize(text, path)
        self.index = 0
        self.package = ""

    def error(self, reason: str) -> SchemaError:
        line = self.tokens[min(self.index, len(self.tokens) - 1)].line if self.tokens else 1
        return SchemaError(self.path, line, reason)

    def peek(self) -> str | None:
        return self.tokens[self.index].text if self.index < len(self.tokens) else None

    def take(self) -> str:
        if self.index >= len(self.tokens):
            raise self.error("unexpected end of file")
        token = self.tokens[self.index].text
        self.index += 1
        return token

    def expect(self, text: str) -> None:
        token = self.take()
        if token != text:
            self.index -= 1
            raise self.error(f"expected {text!r}, found {token!r}")

    def identifier(self, what: str) -> str:
        token = self.take()
        if not _IDENTIFIER.match(token):
            self.index -= 1
            raise self.error(f"expected {what}, found {token!r}")
        return token

    def parse_file(self) -> list[StructDef]:
        structs: list[StructDef] = []
        while self.peek() is not None:
            keyword = self.take()
            if keyword == "package":
                self.package = self.take()
                self.expect(";")
            elif keyword == "struct":
                structs.append(self.parse_struct())
            else:
                self.index -= 1
                raise self.error(f"expected 'package' or 'struct', found {keyword!r}")
        return structs

    def parse_struct(self) -> StructDef:
        name = self.identifier("a struct name")
        self.expect("{")
        members: list[Member] = []
        constants: list[Constant] = []
        while self.peek() != "}":
            if self.peek() == "const":
                self.take()
                constants.extend(self.parse_constants())
            else:
                self.parse_members(members)
        self.expect("}")
        return StructDef(self.package, name, tuple(members), tuple(constants), self.path)

    def parse_constants(self) -> Iterator[Constant]:
        type_name = self.take()
        if type_name not in PRIMITIVE_FORMATS:
            self.index -= 1
            raise self.error(f"a constant must have a numeric type, not {type_name!r}")
        while True:
            name = self.identifier("a constant name")
            self.expect("=")
            literal = self.take()
            yield Constant(name, type_name, self.number(literal, type_name))
            if self.take() == ";":
                return
            self.index -= 1
            self.expect(",")

    def number(self, literal: str, type_name: str) -> int | float:
        try:
            if type_name in ("float", "double"):
                return float(literal)
            return int(literal, 0)
        except ValueError:
            raise self.error(f"{literal!r} is not a valid {type_name} value") from None

    def parse_members(self, earlier: list[Member]) -> None:
        """Parse one declaration (`type a[n], b;`) and append its members to `earlier`."""
        type_name = self.qualify(self.take())
        while True:
            name = self.identifier("a member name")
            dims: list[Dimension] = []
            while self.peek() == "[":
                self.take()
                dims.append(self.dimension(self.take(), earlier))
                self.expect("]")
            earlier.append(Member(name, type_name, tuple(dims)))
            if self.take() == ";":
                return
            self.index -= 1
            self.expect(",")

    def qualify(self, type_name: str) -> str:
        if type_name in PRIMITIVE_TYPES or "." in type_name or not self.package:
            return type_name
        return f"{self.package}.{type_name}"

    def dimension(self, size: str, earlier: list[Member]) -> Dimension:
        if size.isdigit():
            if int(size) <= 0:
                raise self.error(f"array size must be positive, not {size}")
            return Dimension(size, is_variable=False)
        for member in earlier:
            if member.name == size:
                if member.type_name not in INTEGER_TYPES or member.dims:
                    raise self.error(f"array size {size!r} must be an integer scalar member")
                return Dimension(size, is_variable=True)
        raise self.error(f"array size {size!r} is not an earlier member")


def parse_lcm(text: str, path: str = "<string>") -> list[StructDef]:
    """Parse the text of one `.lcm` file into its struct definitions."""
    return _Parser(text, path).parse_file()


def load_schema_dir(folder: Path) -> dict[str, StructDef]:
    """Parse every `.lcm` file in `folder` and check that each referenced type exists."""
    structs: dict[str, StructDef] = {}
    for path in sorted(folder.glob("*.lcm")):
        for struct in parse_lcm(path.read_text(encoding="utf-8"), str(path)):
            if struct.full_name in structs:
                raise SchemaError(str(path), 1, f"type {struct.full_name} is defined twice")
            structs[struct.full_name] = struct
    for struct in structs.values():
        for member in struct.members:
            if not member.is_primitive and member.type_name not in structs:
                raise SchemaError(
                    struct.source, 1, f"{struct.full_name}.{member.name}: unknown type {member.type_name!r}"
                )
    return structs


__all__ = [
    "Constant",
    "Dimension",
    "INTEGER_TYPES",
    "Member",
    "PRIMITIVE_FORMATS",
    "PRIMITIVE_TYPES",
    "STRING_MIN_SIZE",
    "StructDef",
    "fingerprint",
    "load_schema_dir",
    "parse_lcm",
]
