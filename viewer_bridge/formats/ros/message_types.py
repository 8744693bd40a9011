"""The ROS 2 message types this package writes and reads, each named once; the world frame's name;
and `TypedCdr`, one message of several types as CDR with its type's name."""

from typing import NamedTuple

WORLD = "world"  # Drake's name for the world link, and ROS's usual fixed frame

# The message types this package writes and reads, each named once.
POSE_ARRAY = "geometry_msgs/msg/PoseArray"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
SOLID_PRIMITIVE = "shape_msgs/msg/SolidPrimitive"
MESH = "shape_msgs/msg/Mesh"
PLANE = "shape_msgs/msg/Plane"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"


class TypedCdr(NamedTuple):
    """One message of several types as CDR, with its type's full name (`shape_msgs/msg/Mesh`)."""

    type: str
    cdr: bytes


__all__ = [
    "MARKER_ARRAY",
    "MESH",
    "PLANE",
    "POINT_CLOUD2",
    "POSE_ARRAY",
    "SOLID_PRIMITIVE",
    "TF_MESSAGE",
    "WORLD",
    "WRENCH_STAMPED",
    "TypedCdr",
]
