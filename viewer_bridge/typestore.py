"""A store of LCM types, as plain as a ROS bag reader's: load once, then bytes in, bytes or objects out.

`viewer_bridge.lcm_types(...)` is this module's `lcm_types` (the module has another name, as a
package attribute cannot be both a module and a function).

Usage::

    store = viewer_bridge.lcm_types("path/to/lab_types/")   # + lcmtypes/ + Drake's, when installed
    message = store.decode(data)                            # the type found by its fingerprint
    assert store.encode(message) == data
    cdr = store.to_cdr(data)                                # its ROS 2 message, as CDR
    assert store.from_cdr(cdr, "lab.arm_status_t") == data
    value = store.to_dict(data)                             # {"joint_angles": [...], ...}
    assert store.from_dict(value, "lab.arm_status_t") == data

One naming rule: a dict (and every field path an error names, but for `decode` and `encode`)
uses the ROS 2 field names, the ones ROS 2, MCAP and Foxglove show (`joint_angles` for LCM's
`jointAngles`); arrays in a dict are flat in row-major order, as the ROS 2 message holds them.
`decode` and `encode` work on the generated classes, whose attributes are the LCM member names
(as lcm-gen's classes have them), and their errors name those. A type may be named by its LCM
full name (`lab.arm_status_t`) or its ROS 2 type (`lab_lcm_msgs/msg/ArmStatusT`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from functools import cached_property

from viewer_bridge.errors import DecodeError, EncodeError, UnknownName
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.lcmcodec.library import LcmType, TypeLibrary, ros_named
from viewer_bridge.lcmcodec.serde import LcmMessage, StructCodec

__all__ = ["LcmMessage", "LcmType", "LcmTypes", "TypeLibrary", "lcm_types"]


def lcm_types(*sources: str | os.PathLike[str], drake: bool = True) -> LcmTypes:
    """The project's LCM types, Drake's (when `drake` and pydrake is installed), and those of
    `sources`: `.lcm` files, folders of them (searched recursively), lcm-gen'd Python modules by
    import name, or the folder of an lcm-gen'd package.

    Raises:
        SchemaError: a source that is no `.lcm` file, folder or importable module, or a schema
            that does not parse or resolve (file:line).
    """
    return LcmTypes(TypeLibrary.load([os.fspath(source) for source in sources], drake=drake))


class LcmTypes:
    """Known LCM types: their classes, and each message as LCM, CDR or a dict. Each type's code is
    generated once, when first used, and shared: a nested type has one class wherever it is nested."""

    def __init__(self, library: TypeLibrary) -> None:
        self.library = library  # the ROS 2 face of each type: names, definitions, hashes

    def __repr__(self) -> str:
        return f"LcmTypes({len(self.types)} types)"

    @property
    def types(self) -> tuple[str, ...]:
        """Every known type's full name (`drake.lcmt_iiwa_status`), sorted."""
        return tuple(known.full_name for known in self.library.types())

    def get(self, typename: str) -> type[LcmMessage]:
        """The message class of a type (LCM full name or ROS 2 type): `get("lab.point3_t")(x=1.0)`.

        Raises:
            UnknownName: `typename` names no type of this store (a `KeyError` too).
        """
        full_name = self._type(typename).full_name
        return self.library.codecs(full_name)[full_name].message_class

    def decode(self, data: Buffer, typename: str | None = None) -> LcmMessage:
        """The message of a whole LCM buffer (fingerprint first), of the type its fingerprint names
        (types of one shape share one: the first by name, unless `typename` says which).

        Raises:
            DecodeError: bad bytes, an unknown fingerprint, or another type's.
            UnknownName: `typename` names no type of this store (a `KeyError` too).
        """
        known = self._of(data, typename)
        codec = self.library.codecs(known.full_name)[known.full_name]
        try:
            return codec.decode(data)
        except RecursionError:  # a recursive type nested deeper than Python's stack
            raise DecodeError(known.full_name, "<message>", 0, "nested too deeply") from None

    def encode(self, message: LcmMessage) -> bytes:
        """The LCM bytes of a message of one of this store's classes (`get`, `decode`), fingerprint
        first, as lcm-gen writes them.

        Raises:
            EncodeError: a value that does not fit its field, or a message of no class of this store.
        """
        codec = self._own_codec(message)
        if codec is None:
            name = getattr(type(message), "_type_name", "") or type(message).__name__
            raise EncodeError(name, "<message>", "not a message of this store's classes (get, decode)")
        return codec.encode(message)

    def to_cdr(self, data: Buffer, typename: str | None = None) -> bytes:
        """The CDR (header first) of the ROS 2 message of a whole LCM buffer (its type as `decode`
        finds it).

        Raises:
            DecodeError: a type with no ROS 2 form, bad bytes, or an unknown fingerprint.
            UnknownName: `typename` names no type of this store (a `KeyError` too).
        """
        known = self._of(data, typename)
        try:
            return known.to_cdr(data)
        except DecodeError as error:  # the LCM reader names LCM's fields
            raise ros_named(error) from None

    def from_cdr(self, cdr: Buffer, typename: str) -> bytes:
        """The LCM bytes of the CDR of a type's ROS 2 message: `to_cdr`'s inverse.

        Raises:
            DecodeError: bad CDR, or a type with no ROS 2 form.
            UnknownName: `typename` names no type of this store (a `KeyError` too).
        """
        return self._type(typename).from_cdr(cdr)

    def to_dict(self, data: Buffer, typename: str | None = None) -> dict[str, object]:
        """A whole LCM buffer as a dict of ROS 2 field names, JSON-ready (`json.dumps` takes it):
        nested messages dicts, arrays flat lists, a byte array `{"utf8": text}` or `{"base64": ...}`.
        `from_dict` takes it back. Its type as `decode` finds it.

        Raises:
            DecodeError: bad bytes, an unknown fingerprint, or a type with no ROS 2 form.
            UnknownName: `typename` names no type of this store (a `KeyError` too).
        """
        return self._of(data, typename).to_dict(data, bytes_summary=False)

    def from_dict(self, value: Mapping[str, object], typename: str) -> bytes:
        """The LCM bytes of a dict of ROS 2 field names, as `to_dict` gives (or a Foxglove client
        sends: a missing field is its zero, a missing length field is derived from its arrays, a
        byte array may be a list or a base64 string).

        Raises:
            JsonValueError: a value that is no message of the type (non-finite floats included),
                naming the field, or a type with no ROS 2 form.
            UnknownName: `typename` names no type of this store (a `KeyError` too).
        """
        return self._type(typename).from_dict(dict(value))

    def _type(self, typename: str) -> LcmType:
        try:
            return self.library.get(typename)
        except KeyError:
            known = self.library.for_ros_type(typename)
            if known is None:
                raise UnknownName("LCM or ROS 2 type", typename, list(self.types)) from None
            return known

    def _own_codec(self, message: LcmMessage) -> StructCodec | None:
        """This store's codec of `message`'s type when the message's class is that type's, else None."""
        codec: StructCodec | None = getattr(type(message), "_codec", None)
        if codec is None or codec.type_name not in self._names:
            return None
        own = self.library.codecs(codec.type_name)[codec.type_name]
        return own if own.message_class is type(message) else None

    @cached_property
    def _names(self) -> frozenset[str]:
        return frozenset(self.types)

    def _of(self, data: Buffer, typename: str | None) -> LcmType:
        """The type of `data`: `typename`'s, else the one its fingerprint names (another
        fingerprint than `typename`'s is found by the codec, as any wrong bytes are)."""
        if typename is not None:
            return self._type(typename)
        known = self.library.for_data(data)
        if known is None:
            raise DecodeError(
                "<unknown>", "<fingerprint>", 0, f"fingerprint {bytes(data[:8]).hex()} names no known type"
            )
        return known
