"""A JSON value with a ROS 2 message's field names -> the LCM bytes of the type behind it.

The plan of each struct is built once (its fields by ROS 2 name, each with a checker and packer);
encoding walks the value with loops over array elements and one call per nested message, so the
depth of Python's stack is the depth of the type, never that of the input (ROS 2 types do not
nest themselves). What JSON may say, and what it must not (docs/PROTOCOLS.md, "Any LCM type"):

- The value is an object whose keys are the ROS 2 field names (`joint_position`, not LCM's
  `jointPosition`); a nested message is an object; every array is one flat list in row-major
  order, as the ROS 2 message holds it; a byte array (`uint8[]`) is a list of 0..255, a
  base64 string, or the `{"base64": ...}` or `{"utf8": ...}` object `LcmType.to_dict` writes.
- A missing field takes its zero value: 0, 0.0, false, "", an all-zero nested message, a fixed
  array of zeros, an empty variable array.
- A missing length field is derived from the arrays it sizes (`num_joints` from the length of
  `joint_position`), as a ROS 2 user cannot be asked to compute what the message already says;
  when several arrays give it they must agree; one that appears in a multi-dimensional array
  (`grid[rows][cols]`) is derived once the other dimensions are known. A length field that
  nothing gives is 0. A given length field is checked like one in CDR: every array must then
  hold exactly the product of its dimensions. A missing array is empty, so a length field said
  to be 7 with its array missing is refused rather than filled with zeros (which would command
  zero torques to a robot).
- Types are strict: an integer field takes a JSON integer only (not 3.0, not true), within its
  type's range (`uint8` 0..255, `int8` -128..127, ...); a float field an integer or a float,
  finite (NaN and infinities are not JSON; Python's parser accepts them, the bridge does not),
  within float32's range for `float32`; a bool field true or false only; a string field a string
  encodable as UTF-8 (no lone surrogate; a NUL inside passes, as LCM's length word carries it);
  `null` is no value of any type.
- An array's elements are counted before they are encoded, each at the fewest bytes its type
  takes (a nested message with its fixed arrays, which `{}` fills with zeros, included): an array
  that would take the message past `MESSAGE_LIMIT` (64 MiB), or whose length does not fit its
  length field's type, is refused at once, before anything is built for it.

Every refusal is a `JsonValueError` naming the field path (`joint_position[3]`, `tip.frame_id`).
"""

from __future__ import annotations

import base64
import binascii
import math
import struct
from collections.abc import Callable, Mapping
from typing import Any

from viewer_bridge.errors import JsonValueError
from viewer_bridge.lcmcodec.codegen import closure_min_sizes, element_min_size
from viewer_bridge.lcmcodec.rosnames import field_names
from viewer_bridge.lcmcodec.schema import INTEGER_RANGES, PRIMITIVE_FORMATS, Member, StructDef

MESSAGE_LIMIT = 64 << 20  # bytes of LCM; LCM's UDP multicast carries at most about 4 GB, nobody sends that
_FLOAT32_MAX = 3.4028234663852886e38
_MISSING = object()
_NUMBER = frozenset({int, float})
_INT = frozenset({int})
_BOOL = frozenset({bool})


class _Output(list[Any]):
    """The chunks of one message's LCM, and `least`: the fewest bytes the message can take with
    what is known so far (its type's fixed part, and each variable array at its length)."""

    __slots__ = ("least",)

    def __init__(self, least: int) -> None:
        super().__init__()
        self.least = least


Encode = Callable[[Any, _Output], None]


def _kind(value: Any) -> str:
    """What a JSON value is, in JSON's words (a number or boolean as itself)."""
    if type(value) is bool:
        return "true" if value else "false"
    if type(value) in (int, float):
        return _number(value)
    names = {dict: "an object", list: "an array", str: "a string", type(None): "null"}
    return names.get(type(value), type(value).__name__)


def _scalar_error(type_name: str, field: str, value: Any) -> JsonValueError | None:
    """Why `value` is not a JSON value of LCM type `type_name`, as an error at `field`, or None."""
    if type_name in INTEGER_RANGES:
        low, high = INTEGER_RANGES[type_name]
        if type(value) is not int:
            return JsonValueError("", field, f"expected an integer, got {_kind(value)}")
        if not low <= value <= high:
            return JsonValueError("", field, f"{_number(value)} is out of range {low}..{high}")
        return None
    if type_name in ("float", "double"):
        if type(value) not in _NUMBER:
            return JsonValueError("", field, f"expected a number, got {_kind(value)}")
        try:
            number = float(value)
        except OverflowError:
            return JsonValueError("", field, f"{_number(value)} is too large for a {_float_name(type_name)}")
        if not math.isfinite(number):
            return JsonValueError("", field, f"{_number(value)} is not a finite number")
        if type_name == "float" and abs(number) > _FLOAT32_MAX:
            try:  # struct rounds to the nearest float32 first: what rounds to FLT_MAX is fine
                struct.pack(">f", number)
            except OverflowError:
                return JsonValueError("", field, f"{_number(value)} is out of float32's range")
        return None
    if type_name == "boolean":
        return (
            None
            if type(value) is bool
            else JsonValueError("", field, f"expected true or false, got {_kind(value)}")
        )
    if type_name == "string":
        if type(value) is not str:
            return JsonValueError("", field, f"expected a string, got {_kind(value)}")
        try:
            value.encode("utf-8")
        except UnicodeEncodeError as error:
            return JsonValueError("", field, f"character {error.start} is not encodable as UTF-8")
        return None
    raise AssertionError(type_name)


def _number(value: int | float) -> str:
    """A number as it may be shown: a huge integer by its size (Python will not print one of more
    than 4,300 digits, and nobody wants to read one)."""
    if type(value) is int and value.bit_length() > 64:
        return f"an integer of {value.bit_length()} bits"
    return repr(value)


def _float_name(type_name: str) -> str:
    return "float32" if type_name == "float" else "float64"


def _rehome(type_name: str, error: JsonValueError) -> JsonValueError:
    return JsonValueError(type_name, error.field, error.reason)


class JsonEncoder:
    """The JSON -> LCM path of one type (and, through `_encode`, of the types it nests)."""

    def __init__(
        self,
        struct_: StructDef,
        packed_fingerprint: bytes,
        children: Mapping[str, JsonEncoder],
        min_sizes: Mapping[str, int],
    ) -> None:
        self.type_name = struct_.full_name
        self.packed_fingerprint = packed_fingerprint
        self.struct = struct_
        self._ros = field_names(struct_)
        self.names = {self._ros[member.name]: member for member in struct_.members}
        lengths = {dim.size for member in struct_.members for dim in member.dims if dim.is_variable}
        self._lengths = [member for member in struct_.members if member.name in lengths]
        self._arrays = [m for m in struct_.members if any(dim.is_variable for dim in m.dims)]
        # When every variable array is one-dimensional (most robot types), a length field is
        # simply the length of the first of its arrays that is given: no search needed.
        self._sized: dict[str, list[Member]] | None = None
        if all(len(array.dims) == 1 for array in self._arrays):
            self._sized = {member.name: [] for member in self._lengths}
            for array in self._arrays:  # one pass: a struct may hold thousands of sized arrays
                self._sized[array.dims[0].size].append(array)
        self._children = children
        self._min_sizes = min_sizes  # each type's fewest bytes of body (`codegen.min_sizes`)
        self._steps: list[tuple[Member, Encode]] = [
            (member, self._step(member)) for member in struct_.members
        ]

    def encode(self, value: object) -> bytes:
        """The whole LCM message (fingerprint first) of a JSON value; bad values: JsonValueError."""
        out = _Output(len(self.packed_fingerprint) + self._min_sizes[self.type_name])
        if out.least > MESSAGE_LIMIT:
            raise JsonValueError(
                self.type_name,
                "",
                f"takes at least {out.least} bytes of LCM, more than {MESSAGE_LIMIT} bytes",
            )
        out.append(self.packed_fingerprint)
        self._encode(value, out)
        size = sum(map(len, out))
        if size > MESSAGE_LIMIT:
            raise JsonValueError(self.type_name, "", f"{size} bytes of LCM, more than {MESSAGE_LIMIT}")
        return b"".join(out)

    def _encode(self, value: Any, out: _Output) -> None:
        if type(value) is not dict:
            raise JsonValueError(self.type_name, "", f"expected an object, got {_kind(value)}")
        names = self.names
        for key in value:
            if key not in names:
                raise JsonValueError(self.type_name, str(key), "unknown field")
        lengths = self._resolve_lengths(value)
        for member, step in self._steps:
            ros = self._ros[member.name]
            if member.name in lengths:
                item: Any = lengths[member.name]
            else:
                item = value.get(ros, _MISSING)
            try:
                if member.dims:
                    shape = [lengths[dim.size] if dim.is_variable else dim.count for dim in member.dims]
                    self._array(member, ros, item, shape, out)
                else:
                    step(item, out)
            except JsonValueError as error:
                raise self._nested(error, ros) from None

    def _nested(self, error: JsonValueError, ros: str) -> JsonValueError:
        if error.type_name:  # from a nested message: its path goes under this field
            return error.within(self.type_name, ros)
        return JsonValueError(self.type_name, error.field or ros, error.reason)

    def _resolve_lengths(self, value: dict[str, Any]) -> dict[str, int]:
        """Each length field's value: given (checked as its integer type, not negative), or
        derived from the arrays it sizes, or 0."""
        known: dict[str, int] = {}
        for member in self._lengths:
            ros = self._ros[member.name]
            given = value.get(ros, _MISSING)
            if given is _MISSING:
                continue
            error = _scalar_error(member.type_name, ros, given)
            if error is not None:
                raise _rehome(self.type_name, error)
            if given < 0:
                raise JsonValueError(self.type_name, ros, f"a length field cannot be negative ({given})")
            known[member.name] = given
        derived_from: dict[str, str] = {}
        if self._sized is not None:
            for name, arrays in self._sized.items():
                for array in arrays if name not in known else ():
                    items = self._bytes(
                        array, self._ros[array.name], value.get(self._ros[array.name], _MISSING)
                    )
                    if type(items) is list:
                        known[name] = len(items)
                        derived_from[name] = self._ros[array.name]
                        break
        changed = self._sized is None
        while changed:  # each round derives at least one more length, so it ends
            changed = False
            for array in self._arrays:
                items = self._bytes(array, self._ros[array.name], value.get(self._ros[array.name], _MISSING))
                if type(items) is not list:
                    continue
                unknown = {dim.size for dim in array.dims if dim.is_variable and dim.size not in known}
                if len(unknown) != 1:
                    continue
                name = unknown.pop()
                if sum(1 for dim in array.dims if dim.size == name) != 1:
                    continue
                others = math.prod(
                    known[dim.size] if dim.is_variable else dim.count
                    for dim in array.dims
                    if dim.size != name
                )
                if others == 0:
                    continue
                known[name] = len(items) // others
                derived_from[name] = self._ros[array.name]
                changed = True
        for member in self._lengths:
            if member.name in derived_from:
                low, high = INTEGER_RANGES[member.type_name]
                if known[member.name] > high:
                    raise JsonValueError(
                        self.type_name, self._ros[member.name],
                        f"{known[member.name]}, derived from {derived_from[member.name]}, is more than "
                        f"its type {member.type_name} holds ({high})",
                    )  # fmt: skip
            known.setdefault(member.name, 0)
        return known

    def _bytes(self, member: Member, ros: str, items: Any) -> Any:
        """A byte array given as text, as its list of 0..255: a base64 string (as Foxglove's
        clients send it), or the `{"base64": ...}` or `{"utf8": ...}` object `to_dict` writes.
        Any other value (a list, a missing one), or any other member's, is returned as it is."""
        if member.type_name != "byte":
            return items
        if type(items) is dict and len(items) == 1 and type(text := items.get("utf8")) is str:
            error = _scalar_error("string", ros, text)
            if error is not None:
                raise _rehome(self.type_name, error)
            return list(text.encode("utf-8"))
        encoded = items.get("base64") if type(items) is dict and len(items) == 1 else items
        if type(encoded) is not str:
            return items
        try:
            return list(base64.b64decode(encoded, validate=True))
        except (binascii.Error, ValueError):
            raise JsonValueError(self.type_name, ros, "a byte array's string must be base64") from None

    def _array(self, member: Member, ros: str, items: Any, shape: list[int], out: _Output) -> None:
        count = math.prod(shape)
        fixed = all(not dim.is_variable for dim in member.dims)
        if items is _MISSING:
            if count and not fixed:
                names = [self._ros[dim.size] if dim.is_variable else str(dim.count) for dim in member.dims]
                raise JsonValueError("", ros, f"missing, but {self._said(names, shape)}")
        elif type(items := self._bytes(member, ros, items)) is not list:
            raise JsonValueError("", ros, f"expected an array, got {_kind(items)}")
        if items is not _MISSING and len(items) != count:
            names = [self._ros[dim.size] if dim.is_variable else str(dim.count) for dim in member.dims]
            raise JsonValueError("", ros, f"has {len(items)} elements, but {self._said(names, shape)}")
        self._check_size(member, ros, count, fixed, out)
        if items is _MISSING:  # a fixed array (a variable one is empty): zeros
            if member.type_name in PRIMITIVE_FORMATS:  # every primitive's zero is all zero bits
                out.append(bytes(count * PRIMITIVE_FORMATS[member.type_name][1]))
                return
            items = [""] * count if member.type_name == "string" else [{}] * count
        if member.type_name in PRIMITIVE_FORMATS:
            out.append(_pack_array(member.type_name, ros, items))
        elif member.type_name == "string":
            for index, item in enumerate(items):
                _string(item, f"{ros}[{index}]", out)
        else:
            child = self._children[member.type_name]
            for index, item in enumerate(items):
                try:
                    child._encode(item, out)
                except JsonValueError as error:
                    path = f"{ros}[{index}]" + (f".{error.field}" if error.field else "")
                    raise JsonValueError("", path, error.reason) from None

    def _check_size(self, member: Member, ros: str, count: int, fixed: bool, out: _Output) -> None:
        """Refuse an array of `count` elements that would take the message past MESSAGE_LIMIT,
        before any of it is built. A fixed array is in its type's fewest bytes already; a variable
        one adds its elements' to `out.least`. A nested message that takes no bytes counts as one,
        as it is still one element to build."""
        element = element_min_size(member, self._min_sizes)
        if not fixed:
            out.least += count * element
        if out.least > MESSAGE_LIMIT or count * max(element, 1) > MESSAGE_LIMIT:
            raise JsonValueError(
                "", ros, f"{count} elements of at least {element} bytes each make the message at least "
                f"{max(out.least, count * element)} bytes of LCM, more than {MESSAGE_LIMIT} bytes",
            )  # fmt: skip

    @staticmethod
    def _said(names: list[str], shape: list[int]) -> str:
        if len(shape) == 1:
            return f"{names[0]} = {shape[0]}" if not names[0].isdigit() else f"its size is {shape[0]}"
        return f"{' × '.join(names)} = {' × '.join(map(str, shape))} = {math.prod(shape)}"

    def _step(self, member: Member) -> Encode:
        """The encoder of a member without dimensions (arrays go through `_array`)."""
        ros = self._ros[member.name]
        type_name = member.type_name
        if type_name == "string":
            return lambda value, out: _string("" if value is _MISSING else value, ros, out)
        if type_name in PRIMITIVE_FORMATS:
            packer = struct.Struct(">" + PRIMITIVE_FORMATS[type_name][0]).pack
            zero = _zero(type_name)

            def scalar(value: Any, out: _Output) -> None:
                if value is _MISSING:
                    value = zero
                error = _scalar_error(type_name, ros, value)
                if error is not None:
                    raise error
                out.append(packer(value))

            return scalar
        children = self._children

        def nested(value: Any, out: _Output) -> None:
            children[type_name]._encode({} if value is _MISSING else value, out)

        return nested


def _zero(type_name: str) -> Any:
    return {"string": "", "boolean": False, "float": 0.0, "double": 0.0}.get(type_name, 0)


def _string(value: Any, field: str, out: list[Any]) -> None:
    error = _scalar_error("string", field, value)
    if error is not None:
        raise error
    data = value.encode("utf-8")
    out.append(struct.pack(">I", len(data) + 1))
    out.append(data)
    out.append(b"\0")


def _pack_array(type_name: str, field: str, items: list[Any]) -> bytes:
    """A flat list of one primitive type as LCM's big-endian elements: the whole list checked at
    once when it is right, each element (to name the wrong one) when it is not."""
    code = PRIMITIVE_FORMATS[type_name][0]
    types = set(map(type, items))
    good = False
    if type_name in INTEGER_RANGES:
        low, high = INTEGER_RANGES[type_name]
        good = types <= _INT and (not items or (low <= min(items) and max(items) <= high))
    elif type_name in ("float", "double"):
        good = types <= _NUMBER and _finite(items)
    elif type_name == "boolean":
        good = types <= _BOOL
    if good:
        try:
            return (
                bytes(items)
                if type_name in ("byte", "boolean")
                else struct.pack(f">{len(items)}{code}", *items)
            )
        except (OverflowError, struct.error):
            pass  # a float32 out of range: found below
    for index, item in enumerate(items):
        error = _scalar_error(type_name, f"{field}[{index}]", item)
        if error is not None:
            raise error
    # Every element is right (finite floats whose sum overflowed looked wrong to the screen).
    return bytes(items) if type_name in ("byte", "boolean") else struct.pack(f">{len(items)}{code}", *items)


def _finite(items: list[Any]) -> bool:
    # A NaN or infinity makes the sum non-finite, and so may finite values that overflow it: the
    # caller then checks each element. A huge integer raises OverflowError: the same.
    try:
        return math.isfinite(sum(items))
    except OverflowError:
        return False


def compile_json_encoders(
    structs: Mapping[str, StructDef], fingerprints: Mapping[str, bytes], names: list[str]
) -> dict[str, JsonEncoder]:
    """The JSON -> LCM encoders of types `names` and of every type they nest (none may contain itself)."""
    encoders: dict[str, JsonEncoder] = {}
    closure, min_sizes = closure_min_sizes(structs, names)
    for name in closure:  # children are looked up when used: any order will do
        encoders[name] = JsonEncoder(structs[name], fingerprints[name], encoders, min_sizes)
    return encoders
