"""Generate LCM encoders and decoders from parsed definitions.

For each struct we write Python source once, at import, and compile it: the hot path then runs
straight-line `struct` calls with no per-field interpretation. The generated decoders never trust
the buffer: every read is bounds-checked first, a count is compared with the bytes that remain
before anything is allocated, strings must be NUL-terminated UTF-8 and floats finite. Whatever is
wrong raises one `DecodeError` naming the type, the field path and the byte offset.
"""

from __future__ import annotations

import itertools
import math
import struct
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from viewer_bridge.errors import DecodeError, EncodeError
from viewer_bridge.lcmcodec.codegen import (
    Buffer,
    SourceWriter,
    bad_count,
    call_child,
    element_min_size,
    min_sizes,
    scalar_runs,
    string_error,
    truncated,
)
from viewer_bridge.lcmcodec.schema import PRIMITIVE_FORMATS, Member, StructDef, nested_closure
from viewer_bridge.lcmcodec.schema import fingerprints as all_fingerprints

_FINGERPRINT_FIELD = "<fingerprint>"


class LcmMessage:
    """Base of every generated message class: slots, equality, repr and a plain-dict view."""

    __slots__ = ()
    _type_name: ClassVar[str] = ""
    _codec: ClassVar[StructCodec]

    if TYPE_CHECKING:  # fields are generated from the schema; let the type checker see them

        def __init__(self, **fields: Any) -> None: ...
        def __getattr__(self, name: str) -> Any: ...
        def __setattr__(self, name: str, value: Any) -> None: ...

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The members in wire order (constants are class attributes, not fields)."""
        names: tuple[str, ...] = cls.__slots__
        return names

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(getattr(self, name) == getattr(other, name) for name in self.field_names())

    __hash__ = None  # type: ignore[assignment]  # mutable, like lcm-gen's classes

    def __repr__(self) -> str:
        fields = ", ".join(f"{name}={getattr(self, name)!r}" for name in self.field_names())
        return f"{self._type_name}({fields})"

    def encode(self) -> bytes:
        """Fingerprint plus body, exactly as lcm-gen's generated code writes it."""
        return self._codec.encode(self)

    def to_dict(self) -> dict[str, Any]:
        """Every field, with nested messages turned into dicts too (bytes stay bytes)."""
        return {name: _plain(getattr(self, name)) for name in self.field_names()}


def _plain(value: Any) -> Any:
    if isinstance(value, LcmMessage):
        return value.to_dict()
    if isinstance(value, list | tuple):
        return [_plain(item) for item in value]
    return value


@dataclass(frozen=True)
class StructCodec:
    """Everything generated for one LCM type."""

    definition: StructDef
    message_class: type[LcmMessage]
    fingerprint: int
    min_size: int  # body size with every variable array empty and every string empty
    _encode_body: Callable[[LcmMessage, list[bytes]], None]
    _decode_body: Callable[[Buffer, int, int], tuple[LcmMessage, int]]
    finite: bool = True  # the strictness flag: this codec's decoder refuses NaN and infinities
    # The type and every type it nests, with their fingerprints: what its sibling is compiled from.
    _closure: Mapping[str, tuple[StructDef, int]] = field(default_factory=dict, repr=False, compare=False)

    @property
    def type_name(self) -> str:
        return self.definition.full_name

    @cached_property
    def strict(self) -> StructCodec:
        """This type's codec whose decoder refuses NaN and infinities (itself when it does): the
        same class and encoder, from the one registry."""
        return self if self.finite else self._sibling(True)

    @cached_property
    def lenient(self) -> StructCodec:
        """This type's codec whose decoder passes NaN and infinities, as LCM does (itself when it does)."""
        return self._sibling(False) if self.finite else self

    def _sibling(self, finite: bool) -> StructCodec:
        structs = {name: definition for name, (definition, _) in self._closure.items()}
        fingerprints = {name: value for name, (_, value) in self._closure.items()}
        return compile_codecs(structs, finite=finite, fingerprints=fingerprints)[self.type_name]

    def constant(self, name: str) -> int | float:
        """The value of a `const` declared in the schema (e.g. `BOX`)."""
        for constant in self.definition.constants:
            if constant.name == name:
                return constant.value
        raise KeyError(f"{self.type_name} declares no constant {name!r}")

    @cached_property
    def packed_fingerprint(self) -> bytes:
        return struct.pack(">Q", self.fingerprint)

    def encode(self, message: LcmMessage) -> bytes:
        if not isinstance(message, self.message_class):
            raise EncodeError(self.type_name, "<message>", f"not a {self.type_name}: {message!r}")
        parts = [self.packed_fingerprint]
        self._encode_body(message, parts)
        return b"".join(parts)

    def decode(self, data: Buffer) -> LcmMessage:
        """Decode one whole message: fingerprint, body, and nothing after it."""
        end = len(data)
        expected = self.packed_fingerprint
        if end < 8:
            raise DecodeError(self.type_name, _FINGERPRINT_FIELD, 0, f"truncated: {end} bytes")
        if data[:8] != expected:
            raise DecodeError(
                self.type_name,
                _FINGERPRINT_FIELD,
                0,
                f"fingerprint {bytes(data[:8]).hex()} is not {expected.hex()}",
            )
        message, offset = self._decode_body(data, 8, end)
        if offset != end:
            raise DecodeError(self.type_name, "<end>", offset, f"{end - offset} trailing bytes")
        return message


# --- helpers the generated code calls (kept out of the hot path unless something is wrong) ---


def _nest(flat: Sequence[Any], shape: Sequence[int], leaf: Callable[[Any], Any]) -> Any:
    """Turn a flat sequence into nested lists of `shape`; the innermost rows go through `leaf`."""
    if len(shape) == 1:
        return leaf(flat)
    step = math.prod(shape[1:])
    if len(shape) == 2 and step:  # the common case (e.g. position[num_links][3]), kept flat for speed
        return [leaf(flat[start : start + step]) for start in range(0, shape[0] * step, step)]
    return [_nest(flat[i * step : (i + 1) * step], shape[1:], leaf) for i in range(shape[0])]


def _flatten(value: Any, shape: Sequence[int], type_name: str, field: str) -> Iterator[Any]:
    """Walk nested sequences in row-major order, checking each length against `shape`."""
    if len(value) != shape[0]:
        raise EncodeError(type_name, field, f"has {len(value)} elements, expected {shape[0]}")
    if len(shape) == 1:
        yield from value
        return
    for index, row in enumerate(value):
        yield from _flatten(row, shape[1:], type_name, f"{field}[{index}]")


_EMPTY_ROWS_LIMIT = 1 << 16  # lists an empty multi-dimensional array may have beyond the bytes left


def _check_rows(type_name: str, field: str, offset: int, shape: Sequence[int], end: int) -> None:
    """Refuse an empty multi-dimensional array whose nested lists outnumber the bytes that remain
    (or 65,536, whichever is more): they cost memory and time but no bytes."""
    rows, level = 0, 1
    limit = max(end - offset, _EMPTY_ROWS_LIMIT)
    for size in shape[:-1]:
        level *= size
        rows += level
        if rows > limit:
            raise DecodeError(
                type_name, field, offset, f"shape {tuple(shape)} is {rows}+ empty rows, more than {limit}"
            )


def _check_finite(
    type_name: str, field: str, offset: int, size: int, values: Sequence[float], shape: Sequence[int]
) -> None:
    # The sum is a cheap screen (any NaN or inf makes it non-finite); the scan only runs then, and
    # also finds nothing when finite values merely overflowed the sum. (Not math.fsum: it raises
    # OverflowError on such values.)
    if math.isfinite(sum(values)):
        return
    for index, value in enumerate(values):
        if not math.isfinite(value):
            where = f"{field}{_element_path(index, shape)}"
            raise DecodeError(type_name, where, offset + index * size, f"non-finite value {value}")


def _element_path(index: int, shape: Sequence[int]) -> str:
    """`[i][j]` of the element at flat (row-major) `index` of an array of `shape`."""
    indices = []
    for size in reversed(shape):
        index, remainder = divmod(index, size)
        indices.append(remainder)
    return "".join(f"[{i}]" for i in reversed(indices))


def _unexpected_fields(type_name: str, fields: Mapping[str, Any]) -> TypeError:
    """What a message class's constructor raises for keywords that are none of its members."""
    return TypeError(f"{type_name} has no member {', '.join(map(repr, fields))}")


_U32 = struct.Struct(">I")
_NUMPY_THRESHOLD = 48  # elements; below this, struct.unpack beats numpy's per-call overhead
_ENCODE_ERRORS = (struct.error, OverflowError, TypeError, ValueError, AttributeError, UnicodeError)


# --- code generation ---------------------------------------------------------------------------


def _ident(full_name: str) -> str:
    """A Python identifier for a type name, distinct for distinct names (`a_b.c` is not `a.b_c`)."""
    return full_name.replace("_", "__").replace(".", "_D")


class _StructGenerator:
    """Writes the class, the decoder and the encoder of one struct."""

    def __init__(
        self, struct: StructDef, min_sizes: Mapping[str, int], out: SourceWriter, finite: bool = True
    ) -> None:
        self.struct = struct
        self.finite = finite
        self.min_sizes = min_sizes
        self.out = out
        self.ident = _ident(struct.full_name)
        self.type_literal = repr(struct.full_name)
        self.struct_formats: dict[str, str] = {}

    # The class --------------------------------------------------------------------------------

    def write_class(self) -> None:
        """The message class, bound only as `<ident>_class`: a type's own name (`list`, `bytes`,
        `_U32`) never enters the namespace, where it would stand for a builtin or a helper the
        generated code calls. Its `__init__` takes `**fields`, and `<ident>_init` fills them in:
        a parameter per member would let a member named `range` or `bytes` hide the builtin that
        computes another member's default."""
        out, struct = self.out, self.struct
        names = [member.name for member in struct.members]
        out.line(f"class {self.ident}_class(LcmMessage):")
        with out.indent():
            out.line(f"__slots__ = {tuple(names)!r}")
            out.line(f"_type_name = {self.type_literal}")
            for constant in struct.constants:
                out.line(f"{constant.name} = {constant.value!r}")
            out.line("def __init__(self, **fields):")
            with out.indent():
                out.line(f"{self.ident}_init(self, fields)")
        out.line(f"{self.ident}_class.__name__ = {self.ident}_class.__qualname__ = {struct.name!r}")
        out.line(f"def {self.ident}_init(msg, fields):")
        with out.indent():
            for member in struct.members:
                out.line(f"value = fields.pop({member.name!r}, None)")
                out.line(f"msg.{member.name} = {self.default_value(member)} if value is None else value")
            out.line("if fields:")
            with out.indent():
                out.line(f"raise _unexpected_fields({self.type_literal}, fields)")

    def default_value(self, member: Member) -> str:
        if member.type_name == "string":
            leaf = '""'
        elif member.type_name in ("float", "double"):
            leaf = "0.0"
        elif member.type_name == "boolean":
            leaf = "False"
        elif member.type_name in PRIMITIVE_FORMATS:
            leaf = "0"
        else:
            leaf = f"{_ident(member.type_name)}_class()"
        if not member.dims:
            return leaf
        if any(dim.is_variable for dim in member.dims):
            # Fixed dimensions before the first variable one are filled (`[4][n]` -> four empty rows).
            fixed = [dim.count for dim in itertools.takewhile(lambda dim: not dim.is_variable, member.dims)]
            inner = 'b""' if member.type_name == "byte" and len(member.dims) == len(fixed) + 1 else "[]"
            for size in reversed(fixed):
                inner = f"[{inner} for _ in range({size})]"
            return inner
        shape = [dim.count for dim in member.dims]
        if member.type_name == "byte":
            inner = f"bytes({shape[-1]})"
            shape = shape[:-1]
        else:
            inner = leaf
        for size in reversed(shape):
            inner = f"[{inner} for _ in range({size})]"
        return inner

    # Decoding ---------------------------------------------------------------------------------

    def write_decoder(self) -> None:
        out = self.out
        out.line(f"def {self.ident}_decode(buf, off, end):")
        with out.indent():
            out.line(f"msg = {self.ident}_new({self.ident}_class)")
            for group in self.groups():
                if isinstance(group, list):
                    self.decode_scalars(group)
                else:
                    self.decode_member(group)
            out.line("return msg, off")
        out.line(f"{self.ident}_new = object.__new__")

    def groups(self) -> Iterator[list[Member] | Member]:
        """Runs of fixed-size scalar primitives (read with one struct call) and other members."""
        for scalars, run in scalar_runs(self.struct):
            yield [member for _, member in run] if scalars else run[0][1]

    def struct_name(self, members: list[Member]) -> str:
        fmt = ">" + "".join(PRIMITIVE_FORMATS[m.type_name][0] for m in members)
        name = f"{self.ident}_S{len(self.struct_formats)}"
        self.struct_formats[name] = fmt
        return name

    def decode_scalars(self, members: list[Member]) -> None:
        out, t = self.out, self.type_literal
        sizes = [PRIMITIVE_FORMATS[m.type_name][1] for m in members]
        total = sum(sizes)
        packer = self.struct_name(members)
        out.line(f"if off + {total} > end:")
        with out.indent():
            # Name the first member that does not fit.
            position = 0
            for member, size in zip(members, sizes, strict=True):
                out.line(f"if off + {position + size} > end:")
                with out.indent():
                    out.line(f"raise _truncated({t}, {member.name!r}, off + {position}, {size}, end)")
                position += size
        targets = ", ".join(f"msg.{m.name}" for m in members)
        out.line(f"{targets}{',' if len(members) == 1 else ''} = {packer}.unpack_from(buf, off)")
        position = 0
        for member, size in zip(members, sizes, strict=True):
            if member.type_name in ("float", "double") and self.finite:
                out.line(f"if not _isfinite(msg.{member.name}):")
                with out.indent():
                    out.line(
                        f"raise DecodeError({t}, {member.name!r}, off + {position}, "
                        f"'non-finite value %r' % msg.{member.name})"
                    )
            elif member.type_name == "boolean":
                out.line(f"msg.{member.name} = bool(msg.{member.name})")
            position += size
        out.line(f"off += {total}")

    def shape_expression(self, member: Member) -> str:
        parts = [f"msg.{dim.size}" if dim.is_variable else dim.size for dim in member.dims]
        return "(" + ", ".join(parts) + ",)"

    def decode_member(self, member: Member) -> None:
        out, t, name = self.out, self.type_literal, member.name
        if not member.dims:
            self.decode_element(member, f"msg.{name}", repr(name))
            return
        element_size = max(self.element_min_size(member), 1)
        out.line(f"shape = {self.shape_expression(member)}")
        out.line("count = _prod(shape)")
        out.line(f"if min(shape) < 0 or count * {element_size} > end - off:")
        with out.indent():
            out.line(
                f"raise _bad_count({t}, {name!r}, off, min(shape) if min(shape) < 0 else count, {element_size}, end)"
            )
        if len(member.dims) > 1:
            # An empty array still has its rows: `x[n][m][0]` would be n * m lists for no bytes.
            out.line("if not count:")
            with out.indent():
                out.line(f"_check_rows({t}, {name!r}, off, shape, end)")
        if member.type_name in ("byte", "boolean"):
            self.decode_small_array(member, leaf="bytes" if member.type_name == "byte" else "list")
        elif member.type_name in PRIMITIVE_FORMATS:
            # numpy pays off for long arrays (e.g. a draw's positions); struct for short ones.
            out.line(f"if count > {_NUMPY_THRESHOLD}:")
            with out.indent():
                self.decode_long_array(member)
            out.line("else:")
            with out.indent():
                self.decode_small_array(member, leaf="list")
        else:
            out.line("flat = []")
            out.line("for index in range(count):")
            with out.indent():
                self.decode_element(member, "item", f"'{name}[%d]' % index")
                out.line("flat.append(item)")
            self.assign_nested(member, "flat", "list")

    def decode_long_array(self, member: Member) -> None:
        out, t, name = self.out, self.type_literal, member.name
        code, size = PRIMITIVE_FORMATS[member.type_name]
        out.line(f"array = _frombuffer(buf, '>{code}', count, off)")
        if member.type_name in ("float", "double") and self.finite:
            out.line("if not _isfinite_array(array).all():")
            with out.indent():
                out.line(f"_check_finite({t}, {name!r}, off, {size}, array.tolist(), shape)")
        out.line(f"msg.{name} = array.reshape(shape).tolist()")
        out.line(f"off += count * {size}")

    def decode_small_array(self, member: Member, leaf: str) -> None:
        out, t, name = self.out, self.type_literal, member.name
        code, size = PRIMITIVE_FORMATS[member.type_name]
        if member.type_name == "byte":
            out.line("flat = bytes(buf[off:off + count])")
        else:
            out.line(f"flat = _unpack_from('>%d{code}' % count, buf, off)")
        if member.type_name in ("float", "double") and self.finite:
            out.line(f"_check_finite({t}, {name!r}, off, {size}, flat, shape)")
        elif member.type_name == "boolean":
            out.line("flat = [bool(v) for v in flat]")
        out.line(f"off += count * {size}")
        self.assign_nested(member, "flat", leaf)

    def assign_nested(self, member: Member, flat: str, leaf: str) -> None:
        if len(member.dims) > 1:
            self.out.line(f"msg.{member.name} = _nest({flat}, shape, {leaf})")
        elif leaf == "list":
            self.out.line(f"msg.{member.name} = list({flat})")
        else:
            self.out.line(f"msg.{member.name} = {flat}")

    def element_min_size(self, member: Member) -> int:
        return element_min_size(member, self.min_sizes)

    def decode_element(self, member: Member, target: str, field: str) -> None:
        out, t = self.out, self.type_literal
        if member.type_name == "string":
            # Inlined for speed (link names are read every frame); `_string_error` works out the
            # precise error only when something is wrong.
            error = f"_string_error({t}, {field}, buf, off, end)"
            out.line("if off + 4 > end:")
            with out.indent():
                out.line(f"raise {error}")
            out.line("(length,) = _U32_unpack_from(buf, off)")
            out.line("stop = off + 4 + length")
            out.line("if length == 0 or stop > end or buf[stop - 1] != 0:")
            with out.indent():
                out.line(f"raise {error}")
            out.line("try:")
            with out.indent():
                out.line(f"{target} = _str(buf[off + 4 : stop - 1], 'utf-8')")
            out.line("except UnicodeDecodeError:")
            with out.indent():
                out.line(f"raise {error} from None")
            out.line("off = stop")
            return
        self.call_child(
            f"{target}, off = {_ident(member.type_name)}_decode(buf, off, end)", "DecodeError", field
        )

    def call_child(self, statement: str, error_class: str, field: str) -> None:
        call_child(self.out, statement, error_class, self.type_literal, field)

    # Encoding ---------------------------------------------------------------------------------

    def write_encoder(self) -> None:
        out, t = self.out, self.type_literal
        out.line(f"def {self.ident}_encode(msg, out):")
        with out.indent():
            out.line("field = '<message>'")
            out.line("try:")
            with out.indent():
                for group in self.groups():
                    if isinstance(group, list):
                        names = ", ".join(m.name for m in group)
                        values = ", ".join(f"msg.{m.name}" for m in group)
                        out.line(f"field = {names!r}")
                        out.line(f"out.append({self.struct_name(group)}.pack({values}))")
                    else:
                        out.line(f"field = {group.name!r}")
                        self.encode_member(group)
                if not self.struct.members:
                    out.line("pass")
            out.line("except _ENCODE_ERRORS as error:")
            with out.indent():
                out.line(f"raise EncodeError({t}, field, str(error)) from None")

    def encode_member(self, member: Member) -> None:
        out, t, name = self.out, self.type_literal, member.name
        if not member.dims:
            self.encode_element(member, f"msg.{name}", repr(name))
            return
        out.line(
            f"flat = list(_flatten(msg.{name}, {self.shape_expression(member)}, {t}, {name!r}))"
            if member.type_name != "byte"
            else f"flat = _flatten_bytes(msg.{name}, {self.shape_expression(member)}, {t}, {name!r})"
        )
        if member.type_name == "byte":
            out.line("out.append(flat)")
        elif member.type_name in PRIMITIVE_FORMATS:
            code = PRIMITIVE_FORMATS[member.type_name][0]
            out.line(f"out.append(_pack('>%d{code}' % len(flat), *flat))")
        else:
            out.line("for index, item in enumerate(flat):")
            with out.indent():
                self.encode_element(member, "item", f"'{name}[%d]' % index")

    def encode_element(self, member: Member, source: str, field: str) -> None:
        out, t = self.out, self.type_literal
        if member.type_name == "string":
            out.line(f"data = {source}.encode('utf-8')")
            out.line("out.append(_U32.pack(len(data) + 1))")
            out.line("out.append(data)")
            out.line("out.append(b'\\0')")
            return
        child = _ident(member.type_name)
        out.line(f"if type({source}) is not {child}_class:")
        with out.indent():
            out.line(
                f"raise EncodeError({t}, {field}, 'expected {member.type_name}, got %s' % type({source}).__name__)"
            )
        self.call_child(f"{child}_encode({source}, out)", "EncodeError", field)

    def write_formats(self) -> None:
        for name, fmt in self.struct_formats.items():
            self.out.line(f"{name} = _Struct({fmt!r})")


def _flatten_bytes(value: Any, shape: Sequence[int], type_name: str, field: str) -> bytes:
    if len(shape) == 1:
        if len(value) != shape[0]:
            raise EncodeError(type_name, field, f"has {len(value)} bytes, expected {shape[0]}")
        return bytes(value)
    if len(value) != shape[0]:
        raise EncodeError(type_name, field, f"has {len(value)} elements, expected {shape[0]}")
    return b"".join(_flatten_bytes(row, shape[1:], type_name, f"{field}[{i}]") for i, row in enumerate(value))


def generate_source(
    structs: Mapping[str, StructDef],
    min_sizes: Mapping[str, int],
    finite: bool = True,
    decoders_only: frozenset[str] = frozenset(),
) -> str:
    """The Python source of every class, decoder and encoder for `structs`; of the decoder alone
    for those in `decoders_only` (their class and encoder exist: the namespace holds them)."""
    out = SourceWriter()
    for name, definition in structs.items():
        generator = _StructGenerator(definition, min_sizes, out, finite)
        if name not in decoders_only:
            generator.write_class()
            generator.write_encoder()
        generator.write_decoder()
        generator.write_formats()
        out.line("")
    return out.source()


# The helpers' names are capitalised or start with one underscore; every name the generated code
# defines is `<ident>_<what>`, and `_ident` doubles each underscore of a type's name, so none of
# those starts with a single one: no type's name can take a helper's (or a builtin's).
_HELPERS: Mapping[str, Any] = {
    "LcmMessage": LcmMessage,
    "DecodeError": DecodeError,
    "EncodeError": EncodeError,
    "_Struct": struct.Struct,
    "_U32": _U32,
    "_U32_unpack_from": _U32.unpack_from,
    "_str": str,
    "_frombuffer": np.frombuffer,
    "_isfinite_array": np.isfinite,
    "_unpack_from": struct.unpack_from,
    "_pack": struct.pack,
    "_prod": math.prod,
    "_isfinite": math.isfinite,
    "_nest": _nest,
    "_flatten": _flatten,
    "_flatten_bytes": _flatten_bytes,
    "_truncated": truncated,
    "_bad_count": bad_count,
    "_check_finite": _check_finite,
    "_check_rows": _check_rows,
    "_string_error": string_error,
    "_unexpected_fields": _unexpected_fields,
    "_ENCODE_ERRORS": _ENCODE_ERRORS,
}

# A type's identity in the registry: its name, fingerprint, and the members and constants of it and
# of every type it nests (the fingerprint leaves constants out, and a class carries them).
_Key = tuple[str, int, tuple[tuple[str, tuple[Member, ...], tuple[Any, ...]], ...]]


@dataclass
class _Generated:
    """One type's generated code, shared by every codec of it: one class, one encoder, a decoder
    per strictness (compiled when first asked for), and the codec of each."""

    message_class: type[LcmMessage]
    encode_body: Callable[[LcmMessage, list[bytes]], None]
    decode_bodies: dict[bool, Callable[[Buffer, int, int], tuple[LcmMessage, int]]]
    codecs: dict[bool, StructCodec]


class _Registry:
    """The one registry of LCM codecs in the process: a type (`_Key`) is generated once, whoever
    asks (the viewer's `CODECS`, any number of type stores), so its messages are of one class and
    any codec of the type encodes them. Strictness (`finite`) is a decoder's, not a class's."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._types: dict[_Key, _Generated] = {}

    def compile(
        self, structs: Mapping[str, StructDef], finite: bool, fingerprints: Mapping[str, int]
    ) -> dict[str, StructCodec]:
        with self._lock:
            keys = {name: _key(structs, name, fingerprints[name]) for name in structs}
            namespace: dict[str, Any] = dict(_HELPERS)
            for name, key in keys.items():  # what the new code calls of a type generated before
                known = self._types.get(key)
                if known is not None:
                    ident = _ident(name)
                    namespace[f"{ident}_class"] = known.message_class
                    namespace[f"{ident}_encode"] = known.encode_body
                    if finite in known.decode_bodies:
                        namespace[f"{ident}_decode"] = known.decode_bodies[finite]
            new = {name: structs[name] for name, key in keys.items() if not self._has(key, finite)}
            if new:
                sizes = min_sizes(structs)
                have_class = frozenset(name for name in new if keys[name] in self._types)
                source = generate_source(new, sizes, finite, have_class)
                exec(compile(source, "<lcm codecs generated from lcm types>", "exec"), namespace)  # noqa: S102
                for name, definition in new.items():
                    ident = _ident(name)
                    known = self._types.get(keys[name])
                    if known is None:
                        known = self._types[keys[name]] = _Generated(
                            namespace[f"{ident}_class"], namespace[f"{ident}_encode"], {}, {}
                        )
                    known.decode_bodies[finite] = namespace[f"{ident}_decode"]
                    closure = {n: (structs[n], fingerprints[n]) for n in nested_closure(structs, [name])}
                    codec = StructCodec(definition, known.message_class, fingerprints[name], sizes[name],
                                        known.encode_body, known.decode_bodies[finite], finite, closure)  # fmt: skip
                    known.codecs[finite] = codec
                    if not hasattr(known.message_class, "_codec"):
                        known.message_class._codec = codec  # `message.encode()`: any codec writes the same
            return {name: self._types[key].codecs[finite] for name, key in keys.items()}

    def _has(self, key: _Key, finite: bool) -> bool:
        """Whether the type has its decoder of this strictness already."""
        known = self._types.get(key)
        return known is not None and finite in known.decode_bodies


def _key(structs: Mapping[str, StructDef], name: str, fingerprint: int) -> _Key:
    closure = sorted(nested_closure(structs, [name]))
    return name, fingerprint, tuple((n, structs[n].members, structs[n].constants) for n in closure)


_REGISTRY = _Registry()


def compile_codecs(
    structs: Mapping[str, StructDef],
    *,
    finite: bool = True,
    fingerprints: Mapping[str, int] | None = None,
) -> dict[str, StructCodec]:
    """The codecs of every struct in `structs` (which holds every type they nest), from the one
    registry: each type is generated once in the process and its class shared by every codec of it.

    `finite` is the strictness flag: its decoders refuse NaN and infinite floats with a
    `DecodeError` naming the field and offset (the viewer's formats ask for it: a pose or a
    geometry must be finite); without it they pass them, as LCM does. Encoding never checks:
    whatever a strict or lenient codec encodes, the lenient one decodes back. `fingerprints`
    overrides computed ones (an lcm-gen'd class's own, which is what its publisher writes)."""
    given = dict(fingerprints or {})
    missing = [name for name in structs if not given.get(name)]
    if missing:
        computed = all_fingerprints(structs)
        given.update({name: computed[name] for name in missing})
    return _REGISTRY.compile(structs, finite, given)
