"""Numbers a test process holds alone among all the test processes of this machine: its ROS 2
domain and its block of LCM ports.

Derived from the process id alone (as they were), two test processes running at once (two
worktrees' suites, a stress run beside a suite) shared a domain one time in a hundred, and an
LCM port far more often: then one test's Drake traffic reached the other's bridge and recorder,
and its ROS 2 topics the other's subscribers. Here each number is claimed with an exclusive
`flock` on a file of its own in a directory every test process shares; the kernel releases it
when the process ends, however it ends, so nothing is left to clean up. The lock's descriptor is
not inherited (children do not hold the claim past their parent). When every number is taken
(more test processes at once than there are numbers), the process-id-derived one is used, as before.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

CLAIMS = Path(tempfile.gettempdir()) / "viewer-bridge-test-claims"
# ROS 2 domains 1..101: the ids whose DDS ports (7400 + 250 * domain + ...) stay below Linux's
# ephemeral ports (ROS 2's documentation: 0..101 on Linux); 0 is every user's default domain.
ROS_DOMAINS = range(1, 102)
# LCM: blocks of LCM_BLOCK ports from 61000, above both the DDS ports of those domains and Linux's
# ephemeral ports (32768..60999, where tests/zenoh_peers.py finds free ones).
LCM_FIRST_PORT = 61000
LCM_BLOCK = 100  # lcm_url's offsets: 0..99
LCM_BLOCKS = range(45)  # ports 61000..65499

_held: list[int] = []  # the descriptors of the claims this process holds (open while it lives)


def claim(kind: str, numbers: range, start: int, folder: Path = CLAIMS) -> int | None:
    """The first of `numbers`, from index `start` on (wrapping), that no other live process has
    claimed as `kind` (in `folder`), now this process's; None when every one is taken."""
    folder.mkdir(mode=0o1777, exist_ok=True)
    for step in range(len(numbers)):
        number = numbers[(start + step) % len(numbers)]
        descriptor = os.open(folder / f"{kind}-{number}", os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # held by a live process
            os.close(descriptor)
            continue
        _held.append(descriptor)
        return number
    return None


def ros_domain() -> int:
    """This process's ROS 2 domain."""
    pid = os.getpid()
    found = claim("ros-domain", ROS_DOMAINS, pid)
    return found if found is not None else ROS_DOMAINS[pid % len(ROS_DOMAINS)]


_lcm_block: int | None = None


def lcm_port(offset: int) -> int:
    """Port `offset` (0..LCM_BLOCK-1) of this process's LCM block, claimed on first use."""
    global _lcm_block
    if not 0 <= offset < LCM_BLOCK:
        raise ValueError(f"an LCM port offset is 0..{LCM_BLOCK - 1}, not {offset}")
    if _lcm_block is None:
        pid = os.getpid()
        found = claim("lcm-ports", LCM_BLOCKS, pid)
        _lcm_block = found if found is not None else LCM_BLOCKS[pid % len(LCM_BLOCKS)]
    return LCM_FIRST_PORT + LCM_BLOCK * _lcm_block + offset


def tcp_port(offset: int) -> int:
    """A TCP port for a server a test starts long after choosing it: port `offset` of this
    process's LCM block (TCP and UDP numbers are apart). A free port asked of the kernel when
    the module loads is an ephemeral one, which any outgoing connection on the machine may take
    before the test binds it (the docs tests' servers start minutes after collection); the
    block is above the ephemeral range and no other test process's."""
    return lcm_port(offset)
