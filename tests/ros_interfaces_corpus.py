"""A small corpus of `.msg` definitions ("pkg/msg/Name" -> text), as the LCM type library makes
them, for the interface package builder's tests: two packages, one nesting the other's types;
fixed arrays, sequences, strings, bytes, bools, constants and comments.

`vbtest_base_lcm_msgs` and `vbtest_lcm_msgs` are built into the venv once and kept (rebuilt only
when these texts change); `ROUTER_DEFINITIONS` is removed and built again by the router test,
which needs a type that is not built when the bridge starts.
"""

from __future__ import annotations

BASE = "vbtest_base_lcm_msgs"
MAIN = "vbtest_lcm_msgs"
ROUTER = "vbtest_router_lcm_msgs"

DEFINITIONS: dict[str, str] = {
    f"{BASE}/msg/Point": "# a point in metres\nfloat64 x\nfloat64 y\nfloat64 z\n",
    f"{BASE}/msg/Blob": (
        "# bytes with a name\n"
        "int32 MAX_SIZE=65536\n"
        "int8 KIND_RAW=0\n"
        "int8 KIND_ZIP=1\n"
        "string name\n"
        "int8 kind\n"
        "int32 size\n"
        "uint8[] data\n"
        "bool valid\n"
    ),
    f"{MAIN}/msg/JointSample": (
        "# one sample of a 7-joint arm\n"
        "int32 MAX_JOINTS=7\n"
        "int64 utime\n"
        "int32 num_joints\n"
        "float64[7] position_fixed  # lcm: double position_fixed[7]\n"
        "float64[] velocity\n"
        "float32[] torque\n"
        "string[] joint_names\n"
        "int16[3] flags\n"
        "bool ok\n"
        f"{BASE}/Point tip\n"
        f"{BASE}/Point[] path\n"
        f"{BASE}/Point[2] ends\n"
        f"{BASE}/Blob blob\n"
    ),
    f"{MAIN}/msg/Empty": "# no fields: rosidl adds its placeholder byte\n",
}

ROUTER_DEFINITIONS: dict[str, str] = {
    f"{ROUTER}/msg/Counter": "int64 count\nstring label\nfloat64[3] values\n",
}
