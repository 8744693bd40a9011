"""The bridge's Fast DDS profile: a shared-memory segment that holds its large messages, given
only where the user configured nothing, and gone from the environment once read."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest

from viewer_bridge.transports.fastdds_profile import (
    PROFILE_VARIABLE,
    profile_xml,
    shared_memory_profile,
    why_not_applied,
)
from viewer_bridge.transports.ros2 import RosSettings


def test_the_profile_sizes_the_shared_memory_segment_and_keeps_udp() -> None:
    namespace = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    root = ElementTree.fromstring(profile_xml(32 * 2**20))
    kinds = {
        d.findtext("p:type", namespaces=namespace): d
        for d in root.iterfind(".//p:transport_descriptor", namespace)
    }
    assert set(kinds) == {"SHM", "UDPv4"}
    assert kinds["SHM"].findtext("p:segment_size", namespaces=namespace) == str(32 * 2**20)
    participant = root.find("p:participant", namespace)
    assert participant is not None and participant.get("is_default_profile") == "true"
    used = {element.text for element in participant.iterfind(".//p:userTransports/p:transport_id", namespace)}
    assert used == {d.findtext("p:transport_id", namespaces=namespace) for d in kinds.values()}


@pytest.mark.parametrize(
    ("megabytes", "environ", "profile_in_working_directory", "reason"),
    [
        (32, {}, False, None),
        (32, {"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}, False, None),
        (32, {"RMW_IMPLEMENTATION": "rmw_fastrtps_dynamic_cpp"}, False, None),
        (0, {}, False, "shared_memory_mb is 0"),
        (32, {"RMW_IMPLEMENTATION": "rmw_zenoh_cpp"}, False, "rmw_zenoh_cpp, not Fast DDS"),
        (32, {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}, False, "not Fast DDS"),
        (32, {PROFILE_VARIABLE: "/etc/mine.xml"}, False, "a profile of the user's"),
        (32, {"FASTDDS_DEFAULT_PROFILES_FILE": "/etc/mine.xml"}, False, "a profile of the user's"),
        (32, {}, True, "DEFAULT_FASTRTPS_PROFILES.xml in the working directory"),
        (32, {"SKIP_DEFAULT_XML_FILE": "1"}, True, None),  # Fast DDS skips that file, so ours applies
    ],
)
def test_it_applies_only_to_fast_dds_without_a_profile_of_the_users(
    tmp_path: Path,
    megabytes: int,
    environ: dict[str, str],
    profile_in_working_directory: bool,
    reason: str | None,
) -> None:
    if profile_in_working_directory:
        (tmp_path / "DEFAULT_FASTRTPS_PROFILES.xml").write_text("<profiles/>")
    said = why_not_applied(megabytes, environ, tmp_path)
    if reason is None:
        assert said is None
    else:
        assert said is not None and reason in said


def test_the_variable_and_the_file_last_only_as_long_as_the_block() -> None:
    environ: dict[str, str] = {"ROS_DOMAIN_ID": "3"}
    with shared_memory_profile(16, environ) as path:
        assert path is not None and environ[PROFILE_VARIABLE] == str(path)
        assert "<segment_size>16777216</segment_size>" in path.read_text()
    assert environ == {"ROS_DOMAIN_ID": "3"}
    assert not path.exists() and not path.parent.exists()
    users = {PROFILE_VARIABLE: "/etc/mine.xml"}
    with shared_memory_profile(16, users) as path:
        assert path is None and users == {PROFILE_VARIABLE: "/etc/mine.xml"}  # the user's stays


def test_a_bad_size_is_refused_by_the_settings() -> None:
    with pytest.raises(ValueError, match="shared_memory_mb"):
        RosSettings(shared_memory_mb=-1)


_PROBE = """
import json, os, sys
from viewer_bridge.transports.ros2 import RosSettings, RosTransport
transport = RosTransport(RosSettings(node="segment_probe", shared_memory_mb=int(sys.argv[1])))
sizes = []
for line in open("/proc/self/maps"):
    fields = line.split()
    if len(fields) >= 6 and fields[5].startswith("/dev/shm/fastrtps_") and "_port" not in fields[5]:
        low, high = (int(value, 16) for value in fields[0].split("-"))
        sizes.append(high - low)
print(json.dumps({"largest": max(sizes), "variable": os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE")}))
transport.close()
"""


@pytest.mark.e2e
@pytest.mark.parametrize(("megabytes", "at_least", "below"), [(32, 32 * 2**20, 2**31), (0, 1, 2**20)])
def test_the_nodes_participant_maps_a_segment_of_the_size_asked(
    megabytes: int, at_least: int, below: int
) -> None:
    """In a process of its own (Fast DDS reads profiles once per process): the participant's
    shared-memory segment, as mapped, is the size asked (0: Fast DDS's own 512 KiB), and the
    variable is gone once the node exists."""
    environment = {
        key: value for key, value in os.environ.items() if key not in (PROFILE_VARIABLE, "RMW_IMPLEMENTATION")
    }
    result = subprocess.run(
        [sys.executable, "-c", _PROBE, str(megabytes)],
        capture_output=True,
        text=True,
        timeout=120,
        env=environment,
    )
    assert result.returncode == 0, result.stderr
    seen = json.loads(result.stdout.strip().splitlines()[-1])
    assert at_least <= seen["largest"] < below
    assert seen["variable"] is None
