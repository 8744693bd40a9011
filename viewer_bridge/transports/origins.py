"""Which web pages may talk to a server of the bridge: the check of a request's `Origin` header.

A browser lets any page it shows open a WebSocket, or post a form, to any address, this
machine's loopback included (the same-origin policy does not cover WebSockets); what it does
promise is to name the page's origin (`scheme://host[:port]`, RFC 6454) in the request's
`Origin` header, which the page cannot change. So a server that only local tools and chosen web
apps should reach refuses a request whose `Origin` is another page's. A request without the
header is no browser page's (Foxglove's npm client, a Python script, Drake's render client): it
passes, as the server's address is what guards it.

Trusted always: pages served from this machine's loopback (`http(s)://localhost`, `127.0.0.1`,
`[::1]`, any port), and the web apps a server names (`Origins(trusted=...)`: the Foxglove
server trusts Foxglove's own). A setting adds exact origins or patterns in which `*` stands for
any run of characters other than `/`; `*` alone turns the check off.
"""

from __future__ import annotations

import logging
import re
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterable

from viewer_bridge.errors import HttpRefusal

log = logging.getLogger("viewer_bridge")

ANY_ORIGIN = "*"  # as a whole entry: every origin passes (the check is off)
# Foxglove's web app, old and new host
FOXGLOVE_APPS = ("https://app.foxglove.dev", "https://studio.foxglove.dev")
# scheme://host[:port]: what a browser puts in Origin; "null" is what an opaque origin (a file:// page, a sandbox) sends
_ENTRY = re.compile(r"(?:[a-z][a-z0-9+.-]*://[^/\s]+|null)", re.IGNORECASE)
_LOOPBACK = re.compile(
    r"https?://(?:localhost|127\.0\.0\.1|\[::1\])(?::[0-9]{1,5})?", re.IGNORECASE | re.ASCII
)
_SHOWN = 200  # characters of a refused origin put in a log line or an answer
_REMEMBERED = 1024  # distinct refused origins remembered (each logged once); then the oldest are forgotten


_ASCII_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")


def origin_matches(entry: str, origin: str) -> bool:
    """Whether `origin` is one `entry` allows: every character of the entry stands for itself
    (so `[::1]` is itself, not a class), each `*` for any run of characters other than `/`;
    ASCII letters match in either case (browsers write scheme and host in lower case, a config
    may not; hosts are ASCII, punycode). A `*` never spans a `/`, so the entry and the origin
    split at their slashes into parts matched one to one.

    No regular expression: `[^/]*` repeated backtracks, and an origin of 64 kB against a few
    stars then takes minutes (bench/fuzz.py found it). Each part is matched in linear time:
    the text before its first star is a prefix, after its last a suffix, and every piece
    between is found leftmost (`str.find`), which leaves the most room for the pieces after it.
    """
    entry_parts = entry.translate(_ASCII_LOWER).split("/")
    origin_parts = origin.translate(_ASCII_LOWER).split("/")
    return len(entry_parts) == len(origin_parts) and all(map(_part_matches, entry_parts, origin_parts))


def _part_matches(entry: str, text: str) -> bool:
    """`entry` (no `/`) against `text` (no `/`): see `origin_matches`."""
    if "*" not in entry:
        return entry == text
    first, *middle, last = entry.split("*")
    if len(text) < len(first) + len(last) or not (text.startswith(first) and text.endswith(last)):
        return False
    at, end = len(first), len(text) - len(last)
    for piece in middle:
        found = text.find(piece, at, end)
        if found < 0:
            return False
        at = found + len(piece)
    return True


def is_origin_pattern(entry: str) -> bool:
    """Whether `entry` can match an origin at all: `*`, `null`, or `scheme://host[:port]` (a `*`
    anywhere); a path (`https://example.com/`) never matches, as browsers send none."""
    return entry == ANY_ORIGIN or _ENTRY.fullmatch(entry.replace("*", "x")) is not None


class Origins:
    """The origins a server accepts: loopback pages, `trusted` web apps, and the `allowed` entries."""

    def __init__(self, allowed: Iterable[str] = (), trusted: Iterable[str] = ()) -> None:
        self.allowed = tuple(allowed)
        self.trusted = tuple(trusted)
        self.checked = ANY_ORIGIN not in self.allowed
        self._entries = (*self.trusted, *self.allowed)

    def allows(self, origin: str | None) -> bool:
        """Whether a request with this `Origin` header value (None: no header) may be served."""
        if origin is None or not self.checked:
            return True
        origin = origin.strip()
        return _LOOPBACK.fullmatch(origin) is not None or any(
            origin_matches(entry, origin) for entry in self._entries
        )

    def describe(self) -> str:
        """What passes, in a few words, for a start-up line."""
        if not self.checked:
            return "origin check off"
        named = ", ".join((*self.trusted, *self.allowed))
        return "origins: loopback pages" + (f", {named}" if named else "")


def shown(origin: str) -> str:
    """An origin as a log line or an answer may carry it: clipped, and quoted when it holds
    characters that could forge a line (a header value is any latin-1 byte but CR LF)."""
    clipped = origin[:_SHOWN] + ("..." if len(origin) > _SHOWN else "")
    return clipped if clipped.isprintable() else ascii(clipped)


class OriginGate:
    """`Origins` at a server's door: the refusal of a request's origins, each distinct refused
    origin logged once, naming the setting that would allow it (`allow_with(origin)`)."""

    def __init__(self, origins: Origins, what: str, allow_with: Callable[[str], str]) -> None:
        self.origins = origins
        self._what = what  # who was refused, for the log line: "foxglove client"
        self._allow_with = allow_with
        self._logged: OrderedDict[str, None] = OrderedDict()
        self._lock = threading.Lock()

    def refusal(self, origins: list[str]) -> HttpRefusal | None:
        """None when every `Origin` header of a request (usually one, none for a non-browser
        client) passes; else the 403 refusal naming the first that does not."""
        foreign = next((origin for origin in origins if not self.origins.allows(origin)), None)
        if foreign is None:
            return None
        origin = shown(foreign.strip())
        reason = f"{self._what} from origin {origin} refused (403): allow it with {self._allow_with(origin)}"
        refusal = HttpRefusal(403, "origin_refused", reason)
        if self._first_refusal(origin):
            log.warning("%s", refusal)
        return refusal

    def _first_refusal(self, origin: str) -> bool:
        with self._lock:
            if origin in self._logged:
                return False
            self._logged[origin] = None
            if len(self._logged) > _REMEMBERED:
                self._logged.popitem(last=False)
            return True
