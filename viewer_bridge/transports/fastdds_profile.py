"""A Fast DDS profile for the bridge's own participant: a shared-memory segment large enough for
what it publishes.

Fast DDS hands a sample to readers on the same host through a shared-memory segment of the
writer's participant, 512 KiB unless a profile says otherwise. A 1000-link scene's MarkerArray is
about 248 kB, so two of them fill it: a sample published while earlier ones are still being read
finds no room, is left to the reliable protocol's repair, and with KEEP_LAST history a newer
sample replaces it before that comes. At 2 kHz of 1000-link draws (poses, TF and markers, one
node), 3-24% of each topic's messages were lost that way between the bridge and an rclpy
subscriber; with a 32 MiB segment, none.

So, asked to (`ros.shared_memory_mb`), and unless the user configured Fast DDS themselves, the
bridge gives its participant a larger segment. It is not the default: at 30,000 small messages a
second from a bridge pinned to one core, a 32 MiB segment delivered 78-100% (four runs) where Fast
DDS's own delivered 100% (three), and why is not understood yet. Fast DDS reads its default
profiles once per process, when it makes the first participant, from the file
`FASTRTPS_DEFAULT_PROFILES_FILE` names (and `DEFAULT_FASTRTPS_PROFILES.xml` in the working
directory): `shared_memory_profile` names a file of ours only around that moment, then removes the
variable and the file, so nothing the bridge starts later inherits them.

Fast DDS zeroes the segment whole when it makes it: the size asked is memory the process holds.
The profile lists the transports Fast DDS would use anyway, shared memory and UDPv4. Under
`ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` rmw_fastrtps adds its own pair after them and keeps
discovery on this host as always; the range and static peers are the middleware's, untouched.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, MutableMapping
from pathlib import Path

PROFILE_VARIABLE = "FASTRTPS_DEFAULT_PROFILES_FILE"  # Fast DDS 2.x reads this one
SKIP_VARIABLE = "SKIP_DEFAULT_XML_FILE"  # "1": Fast DDS skips the working directory's file
WORKING_DIRECTORY_PROFILE = "DEFAULT_FASTRTPS_PROFILES.xml"
FAST_DDS_RMWS = ("rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp")  # "": Jazzy's default, Fast DDS

_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>viewer_bridge_shm</transport_id>
      <type>SHM</type>
      <segment_size>{segment_bytes}</segment_size>
    </transport_descriptor>
    <transport_descriptor>
      <transport_id>viewer_bridge_udp</transport_id>
      <type>UDPv4</type>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="viewer_bridge" is_default_profile="true">
    <rtps>
      <userTransports>
        <transport_id>viewer_bridge_shm</transport_id>
        <transport_id>viewer_bridge_udp</transport_id>
      </userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
    </rtps>
  </participant>
</profiles>
"""


def profile_xml(segment_bytes: int) -> str:
    """The profile: Fast DDS's usual transports, the shared-memory one with `segment_bytes`."""
    return _PROFILE.format(segment_bytes=segment_bytes)


def why_not_applied(megabytes: int, environ: MutableMapping[str, str], working_directory: Path) -> str | None:
    """Why the bridge leaves Fast DDS's profile alone here, or None when it gives its own."""
    if megabytes <= 0:
        return "shared_memory_mb is 0 (Fast DDS's own segment)"
    if environ.get("RMW_IMPLEMENTATION", "") not in ("", *FAST_DDS_RMWS):
        return f"the middleware is {environ['RMW_IMPLEMENTATION']}, not Fast DDS"
    for variable in (PROFILE_VARIABLE, "FASTDDS_DEFAULT_PROFILES_FILE"):  # the latter: Fast DDS 3's name
        if environ.get(variable):
            return f"Fast DDS has a profile of the user's ({variable})"
    if environ.get(SKIP_VARIABLE) != "1" and (working_directory / WORKING_DIRECTORY_PROFILE).is_file():
        return f"Fast DDS has a profile of the user's ({WORKING_DIRECTORY_PROFILE} in the working directory)"
    return None


@contextlib.contextmanager
def shared_memory_profile(
    megabytes: int, environ: MutableMapping[str, str] | None = None
) -> Iterator[Path | None]:
    """Around the creation of this process's first DDS participant: the profile's file, named by
    `FASTRTPS_DEFAULT_PROFILES_FILE` (None when `why_not_applied` says it is not used); on exit
    the variable and the file are gone. A participant made earlier in the process has read its
    profiles already and is unchanged, as is every later one: they all share the first's."""
    environ = os.environ if environ is None else environ
    if why_not_applied(megabytes, environ, Path.cwd()) is not None:
        yield None
        return
    with tempfile.TemporaryDirectory(prefix="viewer-bridge-fastdds-") as folder:
        path = Path(folder) / "profile.xml"
        path.write_text(profile_xml(megabytes * 2**20))
        environ[PROFILE_VARIABLE] = str(path)
        try:
            yield path
        finally:
            del environ[PROFILE_VARIABLE]
