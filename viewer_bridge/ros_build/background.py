"""ROS 2 interface packages built in the background while the bridge runs.

A route may publish a type whose interface package is not built yet (an LCM type met for the first
time). Building it takes tens of seconds of CMake; the routes must not wait for it. The builder
runs each build on a thread of its own (`ros_interfaces.build`, whose steps are subprocesses) and
keeps a state per package: absent -> building -> ready, or failed with the reason. Once built, the
package is imported in this process: it is installed in the venv's site-packages (already on
`sys.path`) and its type support libraries in the venv's `lib/`, which the ROS wheels' start-up
hook put on `LD_LIBRARY_PATH` for this process, so only the import finders' caches need clearing.
"""

from __future__ import annotations

import enum
import importlib
import logging
import sys
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from viewer_bridge.errors import BridgeError
from viewer_bridge.ros_build import interfaces as ros_interfaces

log = logging.getLogger("viewer_bridge")


class BuildState(enum.Enum):
    ABSENT = "absent"
    BUILDING = "building"
    READY = "ready"
    FAILED = "failed"


@dataclass(frozen=True)
class BuildStatus:
    state: BuildState
    reason: str = ""  # why it failed: one line naming the package and its build log


class InterfaceBuilder:
    """Builds interface packages from `definitions(package)` ("pkg/msg/Name" -> `.msg` text of
    that package and the packages it uses) into the environment at `prefix`, one thread per build
    (builds of one environment wait for each other on its lock file)."""

    def __init__(
        self,
        definitions: Callable[[str], Mapping[str, str]],
        prefix: str | Path = sys.prefix,
        jobs: int = 1,  # the routes keep running on this machine: one compiler at a time
    ) -> None:
        self._definitions = definitions
        self._prefix = Path(prefix)
        self._jobs = jobs
        self._states: dict[str, BuildStatus] = {}
        self._changed = threading.Condition()

    def knows(self, package: str) -> bool:
        """Whether the definitions hold package `package` (so that it can be built)."""
        try:
            names = self._definitions(package)
        except BridgeError:  # a type that cannot be said in ROS 2 (recursive): built it cannot be
            return False
        return any(name.startswith(f"{package}/msg/") for name in names)

    def status(self, package: str) -> BuildStatus:
        with self._changed:
            return self._status(package)

    def request(self, package: str) -> BuildStatus:
        """Start building `package` unless it was asked for before; its status now (never waits)."""
        with self._changed:
            status = self._states.get(package)
            if status is not None:
                return status
            status = self._states[package] = BuildStatus(BuildState.BUILDING)
        threading.Thread(target=self._build, args=(package,), name=f"build {package}", daemon=True).start()
        return status

    def wait(self, package: str, timeout: float) -> BuildStatus:
        """Its status once it is no longer building, or after `timeout` seconds."""
        with self._changed:
            self._changed.wait_for(lambda: self._status(package).state is not BuildState.BUILDING, timeout)
            return self._status(package)

    def _status(self, package: str) -> BuildStatus:  # the caller holds the condition's lock
        return self._states.get(package, BuildStatus(BuildState.ABSENT))

    def _build(self, package: str) -> None:
        try:
            definitions = self._definitions(package)
            # Never pip: a message on a bus must not install software (the tools must be there already).
            ros_interfaces.build(
                definitions, self._prefix, self._jobs, log=log.info, only=[package], install_wheels=False
            )
            importlib.invalidate_caches()  # the finders cached site-packages' listing before it existed
            importlib.import_module(f"{package}.msg")
            status = BuildStatus(BuildState.READY)
        except BridgeError as error:
            status = BuildStatus(BuildState.FAILED, f"ROS 2 interface package {package} not built: {error}")
        except Exception as error:  # built, but the import failed: say so, as any other failure
            status = BuildStatus(
                BuildState.FAILED, f"ROS 2 interface package {package} built but not importable: {error!r}"
            )
        if status.state is BuildState.FAILED:
            log.error("%s", status.reason)
        with self._changed:
            self._states[package] = status
            self._changed.notify_all()
