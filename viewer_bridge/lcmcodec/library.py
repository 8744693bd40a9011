"""Every LCM type the bridge knows, and each one's ROS 2 face: names, definitions, CDR, JSON.

Usage::

    library = TypeLibrary.load(["path/to/lab_types/", "exlcm"])   # + lcmtypes/ + Drake's `drake`
    known = library.for_data(data)                                 # by the first 8 bytes
    if known is not None and known.ros_type is not None:
        cdr = known.to_cdr(data)                                   # for /lcm/<channel>

    back = library.for_ros_type("drake_lcm_msgs/msg/LcmtIiwaCommand")  # or "drake_lcm_msgs/LcmtIiwaCommand"
    lcm = back.from_cdr(cdr)                                       # a ROS 2 message -> LCM bytes
    lcm = back.from_dict({"utime": 1, "joint_position": [0.0] * 7})  # a Foxglove client's JSON -> LCM bytes

Types come from `.lcm` files, folders of them (searched recursively) and lcm-gen'd Python
modules by import name; the project's own `lcmtypes/` always, and pydrake's `drake` module when
it can be imported. All of them become the same `StructDef`s (`schema`), and one mapping
(`rosmsg`) gives each its ROS 2 message or the reason it has none. A type's codecs are
generated when it is first used, together with the types it nests.
"""

from __future__ import annotations

import importlib.util
import threading
from collections.abc import Callable, Mapping, Sequence
from functools import cached_property
from pathlib import Path
from typing import TypeVar

from viewer_bridge.errors import DecodeError, Held, JsonValueError, SchemaError
from viewer_bridge.lcmcodec.cdr import CdrTranscoder, compile_transcoders
from viewer_bridge.lcmcodec.cdr_to_lcm import LcmEncoder, compile_encoders
from viewer_bridge.lcmcodec.codecs import STRUCTS
from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.lcmcodec.json_to_lcm import JsonEncoder, compile_json_encoders
from viewer_bridge.lcmcodec.jsonview import message_json
from viewer_bridge.lcmcodec.pymodule import structs_from_module
from viewer_bridge.lcmcodec.rosmsg import RosMapping, map_to_ros
from viewer_bridge.lcmcodec.rosnames import field_path
from viewer_bridge.lcmcodec.schema import (
    Member,
    StructDef,
    check_references,
    fingerprints,
    load_lcm_files,
    nested_closure,
)
from viewer_bridge.lcmcodec.serde import StructCodec, compile_codecs

_T = TypeVar("_T")
_Compile = Callable[[Mapping[str, StructDef], Mapping[str, bytes], list[str]], dict[str, _T]]
DRAKE_MODULE = "drake"  # pydrake's wheel ships Drake's lcm-gen'd types as this module


class LcmType:
    """One known LCM struct, and its ROS 2 face."""

    def __init__(self, library: TypeLibrary, definition: StructDef, packed_fingerprint: bytes) -> None:
        self._library = library
        self.definition = definition
        self.full_name = definition.full_name
        self.packed_fingerprint = packed_fingerprint
        self.source = definition.where
        message = library._mapping.messages.get(self.full_name)
        self.ros_type: str | None = message.ros_type if message else None
        self.refused: str | None = library._mapping.refused.get(self.full_name)

    def __repr__(self) -> str:
        return f"LcmType({self.full_name!r}, ros_type={self.ros_type!r})"

    @cached_property
    def ros2msg(self) -> str:
        """The `ros2msg` schema (MCAP, Foxglove): the definition, then each nested type's; "" when refused."""
        return self._library._mapping.ros2msg(self.full_name) if self.refused is None else ""

    @cached_property
    def rihs01(self) -> str:
        """`RIHS01_<64 hex>`, the type hash rmw_zenoh announces; "" when refused."""
        return self._library._mapping.rihs01(self.full_name) if self.refused is None else ""

    @property
    def msg_definition(self) -> str:
        """The `.msg` text of this type alone, as the bridge announces it; "" when refused."""
        message = self._library._mapping.messages.get(self.full_name)
        return message.definition if message is not None else ""

    @property
    def msg_file(self) -> str:
        """The `.msg` text with the `.lcm` file's comments, as `ros-interfaces generate` writes it; "" when refused."""
        message = self._library._mapping.messages.get(self.full_name)
        return message.documented if message is not None else ""

    def to_cdr(self, data: Buffer) -> bytes:
        """The whole LCM message (fingerprint included) as CDR, header included; bad bytes: DecodeError."""
        if self.refused is not None:
            raise DecodeError(self.full_name, "<type>", 0, f"has no ROS 2 form: {self.refused}")
        # Later calls go straight to the transcoder, bound on this instance: a message of a kept
        # layout takes about a microsecond, and a call in between is a tenth of it.
        self.to_cdr = self.transcoder.transcode  # type: ignore[method-assign]
        return self.to_cdr(data)

    def to_dict(self, data: Buffer, *, bytes_summary: bool = True) -> dict[str, object]:
        """Every field, JSON-ready, in the form `from_dict` takes back: keys the ROS 2 field names
        (`joint_position`; a type with no ROS 2 form for its names keeps its LCM ones), arrays
        flat in row-major order, nested messages as objects. A byte array is its size and CRC-32
        unless `bytes_summary` is False, then `{"utf8": text}` or `{"base64": ...}`. Bad bytes:
        `DecodeError`, its field path in the same names."""
        codec = self._library.codecs(self.full_name)[self.full_name]
        try:
            message = codec.decode(data)
        except RecursionError:  # a recursive type nested deeper than Python's stack
            raise DecodeError(self.full_name, "<message>", 0, "nested too deeply") from None
        except DecodeError as error:
            raise ros_named(error) from None
        return message_json(message, bytes_summary=bytes_summary)

    def from_cdr(self, data: Buffer) -> bytes:
        """The CDR of this type's ROS 2 message (4-byte header first, little-endian as ROS 2
        writes it) as the whole LCM message, fingerprint first: byte for byte what lcm-gen's
        `encode` writes for the same values.

        Refused with a `DecodeError` naming the ROS 2 field path and the byte offset (counted
        after the header), and nothing returned: a header other than little-endian CDR; too few
        bytes, or more than the message (beyond the up to 3 that pad it to a multiple of 4); a
        sequence whose count is not what LCM's length fields say (`joint_position` must hold
        exactly `num_joints` elements, a flattened `grid[rows][cols]` exactly rows × cols, a
        fixed-size multi-dimensional array the product of its sizes) or a negative length field;
        a count that could not fit in the bytes left (checked before anything is allocated); a
        string of length 0, without its NUL or not UTF-8 (a NUL inside passes: LCM's length word
        carries it, as `to_cdr` does the other way); a bool byte other than 0 or 1 (Fast CDR refuses those too; LCM
        would read any as true and hide bytes that are not this message). A type with no ROS 2
        form raises as `to_cdr` does. ROS 2 constants are not serialized: nothing is read for them.
        """
        if self.refused is not None:
            raise DecodeError(self.full_name, "<type>", 0, f"has no ROS 2 form: {self.refused}")
        self.from_cdr = self.encoder.encode  # type: ignore[method-assign]  # as `to_cdr`: a call less
        return self.from_cdr(data)

    def from_dict(self, value: object) -> bytes:
        """A JSON value (already parsed: dicts, lists, str, int, float, bool, None) with the ROS 2
        message's field names, as the whole LCM message (fingerprint first).

        - An object per message, keys the ROS 2 field names (`joint_position`); arrays flat in
          row-major order as the ROS 2 message holds them; a byte array a list of 0..255, a
          base64 string, or the `{"base64": ...}` or `{"utf8": ...}` object `to_dict` writes.
        - A missing field takes its zero value (0, false, "", an all-zero nested message, a fixed
          array of zeros, an empty variable array).
        - A missing length field is derived from the arrays it sizes (`num_joints` from
          `joint_position`; in `grid[rows][cols]` once the other dimension is known), so that a
          ROS 2 user gives nothing the message already says; arrays that disagree, or a given
          length field that disagrees with its arrays, are refused. A length field that nothing
          gives is 0; a missing array is empty, so an array said to have elements must be given.
        - Strict types: an integer field takes an integer (not 3.0, not true) in its type's
          range; a float field an integer or a float, finite (NaN is not JSON), in float32's
          range for `float32`; a bool field true or false; a string field a string encodable as
          UTF-8; `null` is refused everywhere.
        - An array is counted before its elements are encoded: one past its length field's
          type, or past `json_to_lcm.MESSAGE_LIMIT` (64 MiB of LCM), is refused.

        Every refusal is a `JsonValueError` (a `DecodeError`) naming the field path, e.g.
        `joint_position[3]` or `tip.frame_id`; a value that is not an object names none.
        """
        if self.refused is not None:
            raise JsonValueError(self.full_name, "", f"has no ROS 2 form: {self.refused}")
        return self._json_encoder.encode(value)

    def to_json(self, data: Buffer, *, bytes_summary: bool = True) -> dict[str, object]:
        """An alias of `to_dict`, kept for code written before the one name: use `to_dict`."""
        return self.to_dict(data, bytes_summary=bytes_summary)

    def from_json(self, value: object) -> bytes:
        """An alias of `from_dict`, kept for code written before the one name: use `from_dict`."""
        return self.from_dict(value)

    @cached_property
    def transcoder(self) -> CdrTranscoder:
        """The compiled LCM -> CDR path of this type (`to_cdr`), generated when first asked for."""
        return self._library._transcoder(self.full_name)

    @cached_property
    def encoder(self) -> LcmEncoder:
        """The compiled CDR -> LCM path of this type (`from_cdr`), generated when first asked for."""
        return self._library._encoder(self.full_name)

    @cached_property
    def _json_encoder(self) -> JsonEncoder:
        return self._library._json_encoder(self.full_name)


def _importable(module: str) -> bool:
    """Whether `module` can be found (an import hook that refuses it counts as absent)."""
    try:
        return importlib.util.find_spec(module) is not None
    except ImportError:
        return False


class TypeLibrary:
    """The known LCM types, by full name and by fingerprint."""

    def __init__(
        self,
        structs: Mapping[str, StructDef],
        fingerprints: Mapping[str, bytes],
        warnings: list[str],
        drake_left_out: bool = False,
    ) -> None:
        self._structs = dict(structs)
        # Drake's own types (lcmt_iiwa_command ...) were asked for but pydrake's `drake` module is
        # not installed: only the project's copies of Drake's viewer types are known.
        self.drake_left_out = drake_left_out
        self._mapping: RosMapping = map_to_ros(self._structs)
        self._lock = threading.Lock()
        self._codec_sets: dict[str, dict[str, StructCodec]] = {}
        self._transcoders: dict[str, CdrTranscoder] = {}
        self._encoders: dict[str, LcmEncoder] = {}
        self._json_encoders: dict[str, JsonEncoder] = {}
        self.warnings = warnings + [
            f"{name} ({structs[name].where}) has no ROS 2 form: {reason}"
            for name, reason in self._mapping.refused.items()
        ]
        self._types = {name: LcmType(self, self._structs[name], fingerprints[name]) for name in self._structs}
        # Types of one shape share a fingerprint (Drake's lcmt_iiwa_command and lcmt_allegro_command):
        # every one is kept, in name order, and the channel's name picks among them.
        self._by_ros_type = {message.ros_type: name for name, message in self._mapping.messages.items()}
        self._by_fingerprint: dict[bytes, list[LcmType]] = {}
        for name in sorted(self._types):
            known = self._types[name]
            self._by_fingerprint.setdefault(known.packed_fingerprint, []).append(known)

    @classmethod
    def load(cls, sources: Sequence[str] = (), *, drake: bool = True) -> TypeLibrary:
        """The project's types, Drake's (when `drake` and pydrake is installed), and `sources`:
        `.lcm` files, folders of them (searched recursively), lcm-gen'd Python modules by import
        name, or the folder of an lcm-gen'd Python package (imported from its parent folder).

        A parse error is a `SchemaError` with file:line; one name defined twice with different
        contents is one naming both places."""
        structs: dict[str, StructDef] = dict(STRUCTS)
        declared: dict[str, bytes] = {}  # a class's own fingerprint, which its publisher writes
        drake_found = drake and _importable(DRAKE_MODULE)
        modules: list[tuple[str, Path | None]] = [(DRAKE_MODULE, None)] if drake_found else []
        for source in sources:
            path = Path(source)
            files = sorted(path.rglob("*.lcm")) if path.is_dir() else []
            if files:
                _merge(structs, load_lcm_files(files))
            elif path.is_dir() and (path / "__init__.py").is_file() and path.name.isidentifier():
                modules.append((path.name, path.resolve().parent))  # an lcm-gen'd package's folder
            elif path.is_dir() and (generated := _generated_modules(path)):
                modules.extend((name, path.resolve()) for name in generated)  # lcm-gen -p's --ppath
            elif path.is_dir():
                raise SchemaError(
                    source,
                    0,
                    "is a folder with no .lcm files, no __init__.py, and no lcm-gen'd Python "
                    "package or module in it (lcm-gen -p --ppath FOLDER writes FOLDER/<package>/)",
                )
            elif path.is_file():
                _merge(structs, load_lcm_files([path]))
            elif _looks_like_module(source):
                modules.append((source, None))
            else:
                raise SchemaError(source, 0, "no such .lcm file, folder or importable module")
        for module, search in modules:
            loaded = structs_from_module(module, search)
            _merge(structs, {name: definition for name, (definition, _) in loaded.items()})
            for name, (_, packed) in loaded.items():
                declared.setdefault(name, packed)
        check_references(structs)
        warnings: list[str] = []
        packed_fingerprints: dict[str, bytes] = {}
        hashes = fingerprints(structs)
        for name, definition in structs.items():
            computed = hashes[name].to_bytes(8, "big")
            packed_fingerprints[name] = declared.get(name, computed)
            if packed_fingerprints[name] != computed:
                warnings.append(
                    f"{name} ({definition.where}): its class's fingerprint {packed_fingerprints[name].hex()} is not "
                    f"the {computed.hex()} its description gives; using the class's"
                )
        return cls(structs, packed_fingerprints, warnings, drake_left_out=drake and not drake_found)

    def for_data(self, data: Buffer, channel: str = "") -> LcmType | None:
        """The type whose fingerprint starts `data`, or None.

        When several known types share that fingerprint (the same fields under other names), the
        one whose name the channel's holds wins (`IIWA_COMMAND`: `lcmt_iiwa_command`), the longest
        such name first; with none, the first by full name."""
        candidates = self._by_fingerprint.get(bytes(data[:8]))
        if not candidates:
            return None
        if len(candidates) == 1 or not channel:
            return candidates[0]
        said = _letters(channel)
        named = [known for known in candidates if _short_name(known.full_name) in said]
        return max(named, key=lambda known: len(_short_name(known.full_name))) if named else candidates[0]

    def type_of(self, data: Buffer, channel: str = "") -> LcmType:
        """`for_data`, or `Held` (`unknown_type`, naming the fingerprint) for a type not known here:
        what a route of any LCM type counts per channel and goes on."""
        known = self.for_data(data, channel)
        if known is None:
            raise Held(
                "unknown_type",
                f"fingerprint {bytes(data[:8]).hex()} names no known LCM type (add its .lcm files or "
                "module with --lcm-types or the config's lcm_types)",
            )
        return known

    def sharing_fingerprint(self, lcm_type: LcmType) -> list[LcmType]:
        """Every known type whose fingerprint is `lcm_type`'s (itself included), by full name."""
        return list(self._by_fingerprint.get(lcm_type.packed_fingerprint, [lcm_type]))

    def for_ros_type(self, ros_type: str) -> LcmType | None:
        """The known type whose ROS 2 message is `ros_type` (`drake_lcm_msgs/msg/LcmtIiwaCommand`,
        or `drake_lcm_msgs/LcmtIiwaCommand` as Foxglove schema names may say it), or None."""
        package, _, name = ros_type.partition("/")
        name = name.removeprefix("msg/")
        found = self._by_ros_type.get(f"{package}/msg/{name}")
        return self._types[found] if found is not None else None

    def get(self, full_name: str) -> LcmType:
        """The type named `full_name` (`drake.lcmt_iiwa_status`); KeyError if unknown."""
        return self._types[full_name]

    def types(self) -> list[LcmType]:
        """Every known type, sorted by full name."""
        return [self._types[name] for name in sorted(self._types)]

    def ros_definitions(self, *, comments: bool = False) -> dict[str, str]:
        """`pkg/msg/Name` -> `.msg` text of every type that has a ROS 2 form: the text the bridge
        announces and builds, or with `comments` the one with the `.lcm` files' comments carried
        over, for a workspace's packages (both give the same RIHS01 hash)."""
        return {
            message.ros_type: message.documented if comments else message.definition
            for message in self._mapping.messages.values()
        }

    def codecs(self, full_name: str) -> dict[str, StructCodec]:
        """The LCM codecs of `full_name` and of every type it nests, NaN and infinities allowed
        (`codec.strict` refuses them). Each type's code is generated once in the process, when a
        type that needs it is first asked for, and then shared (`serde`'s one registry): a type has
        one message class wherever it is nested, in this library, another or `codecs.CODECS`."""
        with self._lock:
            if full_name not in self._codec_sets:
                closure = self.closure(full_name)
                fingerprints = {
                    name: int.from_bytes(self._types[name].packed_fingerprint, "big") for name in closure
                }
                self._codec_sets[full_name] = compile_codecs(closure, finite=False, fingerprints=fingerprints)
            return self._codec_sets[full_name]

    def _transcoder(self, full_name: str) -> CdrTranscoder:
        """The LCM -> CDR transcoder of `full_name`, generated when first asked for."""
        return self._compiled(self._transcoders, full_name, compile_transcoders)

    def _encoder(self, full_name: str) -> LcmEncoder:
        """The CDR -> LCM encoder of `full_name`, generated when first asked for."""
        return self._compiled(self._encoders, full_name, compile_encoders)

    def _json_encoder(self, full_name: str) -> JsonEncoder:
        """The JSON -> LCM encoder of `full_name`, built when first asked for."""
        return self._compiled(self._json_encoders, full_name, compile_json_encoders)

    def _compiled(self, cache: dict[str, _T], full_name: str, compile_: _Compile[_T]) -> _T:
        """`cache[full_name]`, made by `compile_` from the type's closure when first asked for."""
        with self._lock:
            if full_name not in cache:
                closure = self.closure(full_name)
                fingerprints = {name: self._types[name].packed_fingerprint for name in closure}
                cache.update(compile_(closure, fingerprints, [full_name]))
            return cache[full_name]

    def closure(self, full_name: str) -> dict[str, StructDef]:
        """`full_name`'s definition and those of every type it nests, at any depth."""
        return {name: self._structs[name] for name in nested_closure(self._structs, [full_name])}


def ros_named(error: DecodeError) -> DecodeError:
    """`error` (the LCM reader's, naming LCM fields) with its field path in ROS 2 names."""
    return DecodeError(error.type_name, field_path(error.field), error.offset, error.reason, error.unit)


def _merge(structs: dict[str, StructDef], new: Mapping[str, StructDef]) -> None:
    """Add `new`; a name already known must have the same members: names, dimensions and types,
    nested types by name too (the fingerprint leaves those out, so two definitions that differ
    only in a nested type's name would hash alike, and the first would decode the other's data)."""
    for name, definition in new.items():
        known = structs.get(name)
        if known is None:
            structs[name] = definition
        elif known.members != definition.members:
            raise SchemaError(
                definition.source,
                definition.line,
                f"type {name} differs from its definition at {known.where}: {_difference(definition, known)}",
            )


def _difference(here: StructDef, there: StructDef) -> str:
    """The first member in which two definitions of one type differ, said for a message."""
    for ours, theirs in zip(here.members, there.members, strict=False):
        if ours != theirs:
            return f"member {_declaration(ours)} here, {_declaration(theirs)} there"
    return f"{len(here.members)} members here, {len(there.members)} there"


def _declaration(member: Member) -> str:
    """A member as a .lcm file declares it: `tlp.list items[n]`."""
    return f"{member.type_name} {member.name}" + "".join(f"[{dim.size}]" for dim in member.dims)


def _generated_modules(folder: Path) -> list[str]:
    """What `lcm-gen --python --ppath folder` wrote there, by import name: a package per LCM
    package (a folder with an `__init__.py`), a module per type of no package (`foo_t.py`)."""
    packages = [child.name for child in sorted(folder.iterdir())
                if child.is_dir() and child.name.isidentifier() and (child / "__init__.py").is_file()]  # fmt: skip
    loose = [child.stem for child in sorted(folder.glob("*.py"))
             if child.stem.isidentifier() and "_get_packed_fingerprint" in child.read_text(errors="replace")]  # fmt: skip
    return packages + loose


def _looks_like_module(source: str) -> bool:
    return all(part.isidentifier() for part in source.split(".")) and not source.endswith(".lcm")


def _letters(text: str) -> str:
    """Lower-case letters and digits only: `IIWA_COMMAND` -> `iiwacommand`."""
    return "".join(character for character in text.lower() if character.isalnum())


def _short_name(full_name: str) -> str:
    """A type's name as a channel would say it: `drake.lcmt_iiwa_command` -> `iiwacommand`."""
    name = full_name.rpartition(".")[2].lower()
    name = name.removeprefix("lcmt_").removesuffix("_t")
    return _letters(name)
