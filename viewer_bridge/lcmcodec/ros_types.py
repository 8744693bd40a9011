"""The ROS 2 types live topics have, onto LCM: their definitions, found where the bridge runs, and
their CDR -> LCM encoders, compiled once per type (docs/PROTOCOLS.md section 14, `ros_topics`).

A type's definition is the `.msg` file its installed interface package ships
(`<prefix>/share/<package>/msg/<Name>.msg`, under this environment's prefix and each of
`AMENT_PREFIX_PATH`'s, as ROS 2 installs them), else rosbags' Jazzy store's: a node's own
package that is built in its workspace is read as it was built, and a standard type needs no
package installed. A topic tells only its type's name, so this is where the bytes' layout comes from.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from viewer_bridge.lcmcodec.cdr_to_lcm import LcmEncoder
from viewer_bridge.lcmcodec.from_ros import map_ros_types
from viewer_bridge.lcmcodec.ros_cdr import compile_ros_encoders

Definition = tuple[list[Any], list[Any]]  # rosbags' fielddefs of one type: constants, fields


def install_prefixes(environ: Mapping[str, str] = os.environ) -> list[Path]:
    """Where interface packages are installed: this environment, then `AMENT_PREFIX_PATH`'s."""
    extra = [Path(part) for part in environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if part]
    return list(dict.fromkeys([Path(sys.prefix), *extra]))


class InstalledDefinitions(Mapping[str, Definition]):
    """ROS 2 definitions by type name (`pkg/msg/Name`): an installed package's `.msg` file, read on
    first ask, else the Jazzy store's. A `.msg` that rosbags cannot parse counts as absent."""

    def __init__(self, prefixes: Sequence[Path] | None = None) -> None:
        from rosbags.typesys import Stores, get_typestore

        self._prefixes = install_prefixes() if prefixes is None else list(prefixes)
        self._store: dict[str, Definition] = get_typestore(Stores.ROS2_JAZZY).fielddefs
        self._read: dict[str, Definition | None] = {}  # installed files read so far (None: none, or bad)
        self._lock = threading.Lock()

    def __getitem__(self, name: str) -> Definition:
        found = self._installed(name)
        if found is None:
            found = self._store.get(name)
        if found is None:
            raise KeyError(name)
        return found

    def __iter__(self) -> Iterator[str]:  # what is known without reading every installed package
        return iter(dict.fromkeys([*(name for name, found in self._read.items() if found), *self._store]))

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def _installed(self, name: str) -> Definition | None:
        with self._lock:
            if name not in self._read:
                self._read[name] = self._parse(name)
            return self._read[name]

    def _parse(self, name: str) -> Definition | None:
        from rosbags.typesys import TypesysError, get_types_from_msg

        package, kind, type_name = (name.split("/") + ["", ""])[:3]
        if kind != "msg" or not type_name:
            return None
        for prefix in self._prefixes:
            path = prefix / "share" / package / "msg" / f"{type_name}.msg"
            if path.is_file():
                try:
                    return get_types_from_msg(path.read_text(), name).get(name)
                except (TypesysError, OSError, UnicodeDecodeError):
                    return None
        return None


class RosTypesOnLcm:
    """Per ROS 2 type, its CDR -> LCM encoder, or why it has none; worked out on the first ask and
    kept (one per router: `Shared.get(RosTypesOnLcm)`)."""

    def __init__(self, definitions: Mapping[str, Definition] | None = None) -> None:
        self._definitions = definitions
        self._found: dict[str, LcmEncoder | str] = {}
        self._lock = threading.Lock()  # routes translate on threads of their own

    def encoder(self, ros_type: str) -> LcmEncoder | str:
        """The encoder of `ros_type`, or the reason it does not map onto LCM."""
        with self._lock:
            found = self._found.get(ros_type)
            if found is None:
                found = self._found[ros_type] = self._make(ros_type)
            return found

    def _make(self, ros_type: str) -> LcmEncoder | str:
        if self._definitions is None:
            self._definitions = InstalledDefinitions()
        if ros_type not in self._definitions:
            return "no definition: no installed interface package ships it, nor has rosbags' Jazzy store it"
        mapping = map_ros_types(self._definitions, [ros_type])
        if ros_type in mapping.refused:
            return mapping.refused[ros_type]
        return compile_ros_encoders(mapping, [ros_type])[ros_type]
