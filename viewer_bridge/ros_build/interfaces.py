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
    APT_PACKAGES as APT_PACKAGES,
)
from viewer_bridge.ros_build.install import (
    BUILD_WHEELS as BUILD_WHEELS,
)
from viewer_bridge.ros_build.install import (
    RUNTIME_WHEELS as RUNTIME_WHEELS,
)
from viewer_bridge.ros_build.install import (
    Confirm as Confirm,
)
from viewer_bridge.ros_build.install import (
    build as build,
)
from viewer_bridge.ros_build.install import (
    built as built,
)
from viewer_bridge.ros_build.install import (
    current as current,
)
from viewer_bridge.ros_build.install import (
    digests as digests,
)
from viewer_bridge.ros_build.install import (
    install as install,
)
from viewer_bridge.ros_build.install import (
    log_path as log_path,
)
from viewer_bridge.ros_build.install import (
    missing as missing,
)
from viewer_bridge.ros_build.install import (
    uninstall as uninstall,
)
from viewer_bridge.ros_build.messages import (
    INTERFACES as INTERFACES,
)
from viewer_bridge.ros_build.messages import (
    Interface as Interface,
)
from viewer_bridge.ros_build.messages import (
    message_text as message_text,
)
from viewer_bridge.ros_build.packages import (
    GENERATED_MARK as GENERATED_MARK,
)
from viewer_bridge.ros_build.packages import (
    WHEEL_INCLUDES_CMAKE as WHEEL_INCLUDES_CMAKE,
)
from viewer_bridge.ros_build.packages import (
    Package as Package,
)
from viewer_bridge.ros_build.packages import (
    check_writable_package as check_writable_package,
)
from viewer_bridge.ros_build.packages import (
    cmake_lists as cmake_lists,
)
from viewer_bridge.ros_build.packages import (
    generate_packages as generate_packages,
)
from viewer_bridge.ros_build.packages import (
    interface_package as interface_package,
)
from viewer_bridge.ros_build.packages import (
    package_xml as package_xml,
)
from viewer_bridge.ros_build.packages import (
    packages as packages,
)
from viewer_bridge.ros_build.packages import (
    write_package as write_package,
)
