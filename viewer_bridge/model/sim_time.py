"""Drake's sim time is integer milliseconds, receive times microseconds; ROS 2 and ign stamps are
(seconds, nanoseconds).

The one place the two are converted, both ways. Negative times floor like Python's `divmod`,
so the nanoseconds are always in [0, 1e9), as both stamp types require.
"""

from __future__ import annotations


def sec_nsec_from_ms(timestamp_ms: int) -> tuple[int, int]:
    seconds, milliseconds = divmod(int(timestamp_ms), 1000)
    return seconds, milliseconds * 1_000_000


def ms_from_sec_nsec(seconds: int, nanoseconds: int) -> int:
    return int(seconds) * 1000 + int(nanoseconds) // 1_000_000


def sec_nsec_from_us(time_us: int) -> tuple[int, int]:
    """A receive time in microseconds (wall clock, as transports stamp messages) as a stamp."""
    seconds, microseconds = divmod(int(time_us), 1_000_000)
    return seconds, microseconds * 1000


def us_from_sec_nsec(seconds: int, nanoseconds: int) -> int:
    """A stamp as microseconds (Drake's `utime`, e.g. of `lcmt_point_cloud`)."""
    return int(seconds) * 1_000_000 + int(nanoseconds) // 1000
