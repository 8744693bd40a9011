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

This module is the face of the three that do the work: `messages` (the Jazzy packages' `.msg`
texts), `packages` (a package's files, written for a workspace) and `install` (builds into the
venv, their locking, logs and stamps, and uninstall).
"""

from viewer_bridge.ros_build.install import (
    APT_PACKAGES,
    BUILD_WHEELS,
    RUNTIME_WHEELS,
    Confirm,
    build,
    built,
    current,
    digests,
    install,
    log_path,
    missing,
    uninstall,
)
from viewer_bridge.ros_build.messages import INTERFACES, Interface, message_text
from viewer_bridge.ros_build.packages import (
    GENERATED_MARK,
    WHEEL_INCLUDES_CMAKE,
    Package,
    check_writable_package,
    cmake_lists,
    generate_packages,
    interface_package,
    package_xml,
    packages,
    write_package,
)

__all__ = [
    "APT_PACKAGES", "INTERFACES", "BUILD_WHEELS", "GENERATED_MARK", "RUNTIME_WHEELS", "WHEEL_INCLUDES_CMAKE",
    "Confirm", "Interface", "Package", "build", "built", "check_writable_package", "cmake_lists", "current", "digests",
    "generate_packages", "install", "interface_package", "log_path", "message_text", "missing", "package_xml",
    "packages", "uninstall", "write_package",
]  # fmt: skip
