"""What an LCM URL says about itself, for the command line's checks and the LCM transport alike."""

from __future__ import annotations


def log_to_write(url: str) -> str | None:
    """The path of the log a `file://PATH?mode=w` (or `mode=a`) URL writes, else None.

    LCM's own file provider writes every message published on such a URL into the log (and
    receives nothing), so whatever publishes on it records: `demo --url` and `run --lcm-url`.
    """
    if not url.startswith("file://"):
        return None
    path, _, query = url.removeprefix("file://").partition("?")
    options = dict(part.partition("=")[::2] for part in filter(None, query.split("&")))
    return path if options.get("mode", "r") in ("w", "a") else None
