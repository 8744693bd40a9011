"""LCM type definitions: parse `.lcm` files and compute their fingerprints.

This module knows what a type *is*; `serde` turns a definition into code that reads and writes it.
The grammar and the fingerprint rules follow the LCM type specification: the base hash covers
each member's name, its type name when primitive, and its dimensions; a compound member adds the
child's hash; the sum is rotated left by one bit.
"""

from __future__ import annotations

import keyword
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from struct import pack as pack_struct

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
# The values a constant of each integer type may hold (`byte` is unsigned).
INTEGER_RANGES: Mapping[str, tuple[int, int]] = {
    "int8_t": (-(1 << 7), (1 << 7) - 1),
    "int16_t": (-(1 << 15), (1 << 15) - 1),
    "int32_t": (-(1 << 31), (1 << 31) - 1),
    "int64_t": (-(1 << 63), (1 << 63) - 1),
    "byte": (0, 255),
}

_MASK64 = (1 << 64) - 1

# The shape a type may have (docs/lcm-types.md, "Limits"). lcm-gen's own rule: a constant array
# size is above 0 and fits int32 (we hold a fixed array's element count, all its constant sizes
# multiplied, to it too). Ours: no real type comes near these (Drake's and ROS 2's nest a few
# levels and use one or two dimensions), and each is far under what Python parses and recurses:
# a type nested deeper, or an array of more dimensions, is refused where it is declared, before
# any code is generated for it.
MAX_ARRAY_SIZE = (1 << 31) - 1
MAX_DIMENSIONS = 32
MAX_NESTING = (
    64  # struct levels: a type holding a type holding ... (a recursive group counts each of its types)
)
# Steps (a struct hashed within a recursive group) one library's fingerprints may take: types that
# nest each other recursively in many ways (a diamond within a cycle) would otherwise take 2^depth.
MAX_HASH_STEPS = 200_000

# What every generated message class (serde's `LcmMessage` and the classes made from it) defines
# beside its fields: a member or constant of one of these names would replace the class's own.
# tests/lcmcodec/test_serde.py holds this set to what the classes really define.
MESSAGE_CLASS_ATTRIBUTES = frozenset({"_codec", "_type_name", "encode", "field_names", "to_dict"})


def name_problem(name: str, what: str, *, attribute: bool) -> str | None:
    """Why `name` cannot name a struct, or (`attribute`) a member or constant, in generated Python
    (ours and lcm-gen's); None when it can. `what` says what it names, for the message."""
    if not _IDENTIFIER.fullmatch(name):
        return f"{what} {name!r} is not an identifier"
    if keyword.iskeyword(name) or name == "self":
        return f"{what} {name!r} is a Python keyword"
    if name.startswith("__"):
        # Python mangles such a name inside a class body (and reserves the dunders for itself):
        # the attribute a class declares would not be the one its code reads.
        return f"{what} {name!r} starts with two underscores, which Python keeps for its own and mangles in classes"
    if attribute and name in MESSAGE_CLASS_ATTRIBUTES:
        return f"{what} {name!r} is the name of an attribute every generated message class has"
    return None


def constant_problem(type_name: str, value: float, text: str) -> str | None:
    """Why `value` (written `text`) cannot be a constant of type `type_name` (a float or double);
    None when it can. Python's code, C's and a ROS 2 .msg file could not all write NaN or an
    infinity as a literal."""
    if not math.isfinite(value):
        return f"{text} is not a finite {type_name}"
    if type_name == "float":
        try:  # struct rounds to the nearest float32 first: what rounds to FLT_MAX fits
            pack_struct(">f", value)
        except OverflowError:
            return f"{text} is out of float's (float32's) range"
    return None


@dataclass(frozen=True, slots=True)
class Dimension:
    """One array dimension: a literal size, or the name of an earlier integer member."""

    size: str  # as the fingerprint hashes it: a literal (`3`, `0x3`), a constant's literal, a member name
    is_variable: bool

    @property
    def count(self) -> int:
        """The number of elements of a fixed dimension (its literal may be hexadecimal)."""
        return int(self.size, 0)

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
    comment: str = field(default="", compare=False)  # the comment just before it in the .lcm file
    trailing: str = field(default="", compare=False)  # the comment after it, from the same line on

    @property
    def is_primitive(self) -> bool:
        return self.type_name in PRIMITIVE_TYPES


@dataclass(frozen=True, slots=True)
class Constant:
    """A `const` declaration; it is a class attribute, not part of the wire format."""

    name: str
    type_name: str
    value: int | float
    text: str = ""  # the literal as written (`0x1F`); an array sized by this constant hashes it
    comment: str = field(default="", compare=False)
    trailing: str = field(default="", compare=False)


@dataclass(frozen=True, slots=True)
class StructDef:
    """One parsed `struct`, with the file it came from for error messages."""

    package: str
    name: str
    members: tuple[Member, ...]
    constants: tuple[Constant, ...]
    source: str  # a file path, or `module NAME` for an lcm-gen'd Python class
    line: int = 1
    comment: str = field(default="", compare=False)

    @property
    def full_name(self) -> str:
        return f"{self.package}.{self.name}" if self.package else self.name

    @property
    def where(self) -> str:
        """Where it was defined, for messages: `path/x.lcm:12`, or `module drake`."""
        return f"{self.source}:{self.line}" if not self.source.startswith("module ") else self.source

    def member(self, name: str) -> Member | None:
        return next((member for member in self.members if member.name == name), None)

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


def nested_closure(structs: Mapping[str, StructDef], names: Iterable[str]) -> list[str]:
    """`names` and every type they nest, at any depth, each once (`names` first)."""
    found: dict[str, None] = {}
    pending = list(reversed(list(names)))
    while pending:
        name = pending.pop()
        if name not in found:
            found[name] = None
            pending.extend(m.type_name for m in structs[name].members if not m.is_primitive)
    return list(found)


def fingerprint(struct: StructDef, structs: Mapping[str, StructDef]) -> int:
    """The 64-bit fingerprint written in front of every encoded message of this type."""
    closure = {name: structs[name] for name in nested_closure(structs, [struct.full_name])}
    return fingerprints(closure)[struct.full_name]


def fingerprints(structs: Mapping[str, StructDef]) -> dict[str, int]:
    """Every type's fingerprint, in time linear in the types' size (`structs` must hold every type
    they nest; `check_references` has refused one nested too deeply).

    LCM's rule hashes a type's children recursively, a type already among its parents counting 0.
    That makes a child's hash depend on its parents only through those of its own recursive group
    (the types it reaches that reach it back): a type entered from outside its group hashes alike
    from anywhere, and is hashed once. Only within a recursive group is the path followed, within
    `MAX_HASH_STEPS`: without the memo, a diamond of 22 types (each holding two of the next) took
    four million steps."""
    group = recursive_groups(structs)
    entered: dict[str, int] = {}
    bases: dict[str, int] = {}
    steps = 0

    def hashed(struct: StructDef, parents: tuple[str, ...]) -> int:
        nonlocal steps
        name = struct.full_name
        if name in parents:
            return 0
        from_outside = not parents or group[parents[-1]] != group[name]
        if from_outside and name in entered:
            return entered[name]
        steps += 1
        if steps > MAX_HASH_STEPS:
            raise SchemaError(struct.source, struct.line, f"{name}: its fingerprint takes more than "
                              f"{MAX_HASH_STEPS} steps (recursive types nesting each other in too many ways)")  # fmt: skip
        if name not in bases:
            bases[name] = struct.base_hash()
        value = bases[name]
        inner = parents + (name,)
        for member in struct.members:
            if not member.is_primitive:
                value += hashed(structs[member.type_name], inner)
        value &= _MASK64
        value = ((value << 1) & _MASK64) + (value >> 63)
        if from_outside:
            entered[name] = value
        return value

    return {name: hashed(struct, ()) for name, struct in structs.items()}


def recursive_groups(structs: Mapping[str, StructDef]) -> dict[str, int]:
    """Each type's recursive group (strongly connected component of the nesting graph), by number:
    Tarjan's algorithm, iterative so that no chain of types is too long for Python's stack. Groups
    are numbered as found, a group after every group it nests."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    group: dict[str, int] = {}
    stack: list[str] = []
    found = 0  # groups

    def children(name: str) -> Iterator[str]:
        return (m.type_name for m in structs[name].members if not m.is_primitive)

    for root in structs:
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        work = [(root, children(root))]
        while work:
            name, pending = work[-1]
            for child in pending:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    work.append((child, children(child)))
                    break
                if child not in group:  # on the stack: in this name's group
                    low[name] = min(low[name], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[name])
                if low[name] == index[name]:
                    while True:
                        member = stack.pop()
                        group[member] = found
                        if member == name:
                            break
                    found += 1
    return group


def nesting_depths(structs: Mapping[str, StructDef]) -> dict[str, int]:
    """Each type's nesting depth: the most struct levels a value of it can hold one inside another
    (a type of primitive members only: 1; a recursive group counts each of its types once)."""
    group = recursive_groups(structs)
    members: dict[int, list[str]] = {}
    for name, number in group.items():
        members.setdefault(number, []).append(name)
    depth: dict[int, int] = {}
    for number in sorted(members):  # a group after every group it nests
        below = (
            depth[group[m.type_name]]
            for name in members[number]
            for m in structs[name].members
            if not m.is_primitive and group[m.type_name] != number
        )
        depth[number] = len(members[number]) + max(below, default=0)
    return {name: depth[number] for name, number in group.items()}


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
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")  # always fullmatch: `$` would take "name\n"


@dataclass(slots=True)
class _Token:
    text: str
    line: int
    comment: str  # the comments between the previous token's line and this token, markers stripped
    trailing: str = ""  # the comments that start on this token's line after it (`; // metres`)


def _tokenize(text: str, path: str) -> list[_Token]:
    """The tokens of `text`, each with the comments around it: a comment that starts on the line
    of the token before it trails that token; the others lead the token after them."""
    tokens: list[_Token] = []
    comments: list[str] = []
    trailing: list[str] = []
    position = 0
    line = 1
    while position < len(text):
        match = _TOKEN.match(text, position)
        if match is None:
            raise SchemaError(path, line, f"unexpected character {text[position]!r}")
        kind = match.lastgroup
        if kind in ("number", "word", "symbol"):
            tokens.append(_Token(match.group(), line, "\n".join(comments)))
            comments = []
            trailing = []
        elif kind in ("line_comment", "block_comment"):
            if tokens and tokens[-1].line == line and not comments:
                trailing.extend(_comment_lines(match.group()))
                tokens[-1].trailing = "\n".join(trailing)
            else:
                comments.extend(_comment_lines(match.group()))
        line += match.group().count("\n")
        position = match.end()
    return tokens


def _comment_lines(comment: str) -> list[str]:
    """The text of a `// ...` or `/* ... */` comment, one item per line, decoration removed."""
    body = comment[2:-2] if comment.startswith("/*") else comment[2:]
    lines = [line.strip().lstrip("*").strip() for line in body.splitlines()]
    return [line for line in lines if line]


class _Parser:
    """A recursive-descent parser over the token list of one file."""

    def __init__(self, text: str, path: str) -> None:
        self.path = path
        self.tokens = _tokenize(text, path)
        self.index = 0
        self.package = ""

    def error(self, reason: str) -> SchemaError:
        return SchemaError(self.path, self.line(), reason)

    def line(self) -> int:
        return self.tokens[min(self.index, len(self.tokens) - 1)].line if self.tokens else 1

    def comment(self) -> str:
        """The comment in front of the next token."""
        return self.tokens[self.index].comment if self.index < len(self.tokens) else ""

    def trailing(self) -> str:
        """The comment after the token just taken, on its line."""
        return self.tokens[self.index - 1].trailing

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

    def identifier(self, what: str, *, attribute: bool = True) -> str:
        """The next token as a name: of a member or constant (`attribute`), or of a struct."""
        token = self.take()
        if not _IDENTIFIER.fullmatch(token):
            self.index -= 1
            raise self.error(f"expected {what}, found {token!r}")
        problem = name_problem(token, what, attribute=attribute)
        if problem is not None:  # lcm-gen's Python, or our own generated codecs, could not name it
            self.index -= 1
            raise self.error(problem)
        return token

    def parse_file(self) -> list[StructDef]:
        structs: list[StructDef] = []
        while self.peek() is not None:
            comment, line = self.comment(), self.line()
            keyword_ = self.take()
            if keyword_ == "package":
                self.package = self.take()
                if not _PACKAGE.fullmatch(self.package):
                    self.index -= 1
                    raise self.error(f"{self.package!r} is not a package name")
                self.expect(";")
            elif keyword_ == "struct":
                structs.append(self.parse_struct(comment, line))
            else:
                self.index -= 1
                raise self.error(f"expected 'package' or 'struct', found {keyword_!r}")
        return structs

    def parse_struct(self, comment: str, line: int) -> StructDef:
        name = self.identifier("a struct name", attribute=False)
        self.expect("{")
        comment = "\n".join(filter(None, (comment, self.trailing())))  # `struct s {  // what s is`
        # By name, so that a struct of 100,000 members is parsed in linear time.
        members: dict[str, Member] = {}
        constants: dict[str, Constant] = {}
        while self.peek() != "}":
            if self.peek() == "const":
                constant_comment = self.comment()
                self.take()
                for constant in self.parse_constants(constant_comment):
                    self.check_new_name(constant.name, members, constants)
                    constants[constant.name] = constant
            else:
                self.parse_members(members, constants)
        self.expect("}")
        return StructDef(
            self.package, name, tuple(members.values()), tuple(constants.values()), self.path, line, comment
        )

    def check_new_name(self, name: str, members: dict[str, Member], constants: dict[str, Constant]) -> None:
        if name in members or name in constants:
            self.index -= 1
            raise self.error(f"{name!r} is declared twice")

    def parse_constants(self, comment: str) -> Iterator[Constant]:
        type_name = self.take()
        if type_name not in PRIMITIVE_FORMATS or type_name in ("boolean", "byte"):  # as lcm-gen
            self.index -= 1
            raise self.error(f"a constant must have a numeric type, not {type_name!r}")
        while True:
            name = self.identifier("a constant name")
            self.expect("=")
            literal = self.take()
            value = self.number(literal, type_name)
            ends = self.take()
            yield Constant(name, type_name, value, literal, comment, self.trailing())
            comment = ""
            if ends == ";":
                return
            self.index -= 1
            self.expect(",")

    def number(self, literal: str, type_name: str) -> int | float:
        try:
            if type_name in ("float", "double"):
                number = float(literal)  # also takes the words `nan` and `inf`: refused next
                problem = constant_problem(type_name, number, literal)
                if problem is not None:
                    self.index -= 1
                    raise self.error(problem)
                return number
            value = int(literal, 0)
        except ValueError:
            self.index -= 1
            raise self.error(f"{literal!r} is not a valid {type_name} value") from None
        low, high = INTEGER_RANGES[type_name]
        if not low <= value <= high:
            self.index -= 1
            raise self.error(f"{literal} does not fit in {type_name}")
        return value

    def parse_members(self, earlier: dict[str, Member], constants: dict[str, Constant]) -> None:
        """Parse one declaration (`type a[n], b;`) and add its members to `earlier`."""
        comment = self.comment()
        type_name = self.qualify(self.take())
        while True:
            name = self.identifier("a member name")
            self.check_new_name(name, earlier, constants)
            dims: list[Dimension] = []
            elements = 1  # of the constant dimensions
            while self.peek() == "[":
                if len(dims) == MAX_DIMENSIONS:
                    raise self.error(f"{name!r} has more than {MAX_DIMENSIONS} array dimensions")
                self.take()
                dims.append(self.dimension(self.take(), earlier, constants))
                elements *= 1 if dims[-1].is_variable else dims[-1].count
                if elements > MAX_ARRAY_SIZE:
                    raise self.error(f"{name!r} has more than {MAX_ARRAY_SIZE} elements (int32's largest)")
                self.expect("]")
            ends = self.take()  # `;` or `,`: a comment after it on its line is this member's
            earlier[name] = Member(name, type_name, tuple(dims), comment, self.trailing())
            comment = ""
            if ends == ";":
                return
            self.index -= 1
            self.expect(",")

    def qualify(self, type_name: str) -> str:
        if type_name in PRIMITIVE_TYPES:
            return type_name
        if not _PACKAGE.fullmatch(type_name):
            self.index -= 1
            raise self.error(f"expected a type, found {type_name!r}")
        if "." in type_name or not self.package:
            return type_name
        return f"{self.package}.{type_name}"

    def dimension(self, size: str, earlier: dict[str, Member], constants: dict[str, Constant]) -> Dimension:
        if size[:1].isdigit():
            try:
                count = int(size, 0)
            except ValueError:
                raise self.error(f"array size {size!r} is not a number") from None
            if not 0 < count <= MAX_ARRAY_SIZE:  # lcm-gen's rule
                raise self.error(
                    f"array size must be from 1 to {MAX_ARRAY_SIZE} (int32's largest), not {size}"
                )
            return Dimension(size, is_variable=False)
        constant = constants.get(size)
        if constant is not None:
            # lcm-gen hashes the constant's literal, as if it had been written in the brackets.
            if constant.type_name not in INTEGER_TYPES or not 0 < int(constant.value) <= MAX_ARRAY_SIZE:
                raise self.error(
                    f"array size {size!r} must be an integer constant from 1 to {MAX_ARRAY_SIZE}"
                )
            return Dimension(constant.text, is_variable=False)
        member = earlier.get(size)
        if member is not None:
            if member.type_name not in INTEGER_TYPES or member.dims:
                raise self.error(f"array size {size!r} must be an integer scalar member")
            return Dimension(size, is_variable=True)
        raise self.error(f"array size {size!r} is neither a constant nor an earlier member")


_PACKAGE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*")  # always fullmatch


def parse_lcm(text: str, path: str = "<string>") -> list[StructDef]:
    """Parse the text of one `.lcm` file into its struct definitions."""
    return _Parser(text, path).parse_file()


def load_schema_dir(folder: Path) -> dict[str, StructDef]:
    """Parse every `.lcm` file in `folder` and check that each referenced type exists."""
    structs = load_lcm_files(sorted(folder.glob("*.lcm")))
    check_references(structs)
    return structs


def load_lcm_files(paths: Iterable[Path]) -> dict[str, StructDef]:
    """Parse `.lcm` files into one table by full name; a name defined twice is an error naming both."""
    structs: dict[str, StructDef] = {}
    for path in paths:
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise SchemaError(str(path), 1, f"cannot read: {error}") from None
        for struct in parse_lcm(text, str(path)):
            if struct.full_name in structs:
                first = structs[struct.full_name]
                raise SchemaError(
                    struct.source, struct.line, f"type {struct.full_name} is also defined at {first.where}"
                )
            structs[struct.full_name] = struct
    return structs


def check_references(structs: Mapping[str, StructDef]) -> None:
    """Refuse a member whose struct type is not in `structs`, and a type nested deeper than
    `MAX_NESTING` levels, naming the file and line of its struct."""
    for struct in structs.values():
        for member in struct.members:
            if not member.is_primitive and member.type_name not in structs:
                raise SchemaError(
                    struct.source,
                    struct.line,
                    f"{struct.full_name}.{member.name}: unknown type {member.type_name!r}",
                )
    depths = nesting_depths(structs)
    deepest = max(depths, key=lambda name: (depths[name], name), default=None)
    if deepest is not None and depths[deepest] > MAX_NESTING:
        struct = structs[deepest]
        raise SchemaError(struct.source, struct.line, f"{deepest} nests types {depths[deepest]} levels deep, "
                          f"more than the {MAX_NESTING} a type may")  # fmt: skip
