"""The Zenoh session: its configuration, opened in the background until a router answers.

`session_config` builds the configuration the way rmw_zenoh does (docs/PROTOCOLS.md section 10):
a Zenoh config file (`ZENOH_SESSION_CONFIG_URI`, or the transport's own `config_file`), else the
bridge's defaults: client mode to `tcp/localhost:7447`, where `rmw_zenohd` listens, with no
listening port and no multicast scouting (a router instead dials no router and listens on
`tcp/127.0.0.1:7447`, where its clients connect); then `ZENOH_CONFIG_OVERRIDE`
(`key=value;key=value`), then the transport's settings. TLS, mTLS and user/password are Zenoh
config keys, passed through.

`Link` opens the session. A client cannot open without a router, so a router that is down at
start is tried again every second while the other routes run; once open, Zenoh itself reconnects
after a router restart and declares the session's subscribers and tokens again. `connected`
says whether a client's router is up now, for counting what cannot be sent; a peer or a router
routes by itself, so what it publishes with no one connected has merely no subscriber.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ParamSpec, TypeVar

import zenoh

from viewer_bridge.errors import InvalidSetting

_log = logging.getLogger("viewer_bridge")
ROUTER_ENDPOINT = "tcp/localhost:7447"  # rmw_zenohd's
ROUTER_LISTEN = "tcp/127.0.0.1:7447"  # where the bridge as a router waits for its clients: this machine's
# Without a config file: a client (or a peer) of the local router that listens nowhere and scouts
# no multicast; a router (which is the local router) dials none and listens where clients connect.
_DEFAULTS = (("connect/endpoints", json.dumps([ROUTER_ENDPOINT])), ("listen/endpoints", "[]"))
_ROUTER_DEFAULTS = (("connect/endpoints", "[]"), ("listen/endpoints", json.dumps([ROUTER_LISTEN])))
# Always: the publication caches that serve TRANSIENT_LOCAL history need timestamped samples.
_REQUIRED = (("timestamping/enabled", "true"),)


def overrides_from_env(text: str) -> list[tuple[str, str]]:
    """`ZENOH_CONFIG_OVERRIDE`: `key=value` pairs separated by `;`, values in JSON5, as
    rmw_zenoh reads it (a pair without `=` is skipped; the value is everything after the first `=`)."""
    pairs = []
    for pair in text.split(";"):
        key, equals, value = pair.partition("=")
        if key.strip() and equals and value:
            pairs.append((key.strip(), value))
    return pairs


def session_config(
    config_file: str | None,
    settings: Mapping[str, Any],
    options: Mapping[str, Any],
    environ: Mapping[str, str],
) -> tuple[str | None, list[tuple[str, str]]]:
    """The config file to start from (None: Zenoh's defaults), and the `(key, JSON5 value)`
    pairs to set on it, in order, later ones winning.

    `settings`: the transport's mode, connect and listen endpoints (None: not set);
    `options`: any Zenoh config keys (`transport/link/tls/root_ca_certificate`: a path).
    """
    file = config_file or environ.get("ZENOH_SESSION_CONFIG_URI") or None
    chosen = overrides_from_env(environ.get("ZENOH_CONFIG_OVERRIDE", ""))
    for key, value in settings.items():
        if value is not None:
            chosen.append((f"{key}/endpoints" if key in ("connect", "listen") else key, json.dumps(value)))
    chosen += [(key, json.dumps(value)) for key, value in options.items()]
    pairs = [] if file else _defaults(_chosen_mode(chosen))
    return file, pairs + chosen + list(_REQUIRED)


def _chosen_mode(pairs: Sequence[tuple[str, str]]) -> str:
    """The mode the last `mode` pair sets (its JSON5 string unquoted), else client."""
    modes = [value.strip().strip("\"'") for key, value in pairs if key.strip("/") == "mode"]
    return modes[-1] if modes else "client"


def _defaults(mode: str) -> list[tuple[str, str]]:
    endpoints = _ROUTER_DEFAULTS if mode == "router" else _DEFAULTS
    return [("mode", json.dumps(mode)), *endpoints, ("scouting/multicast/enabled", "false")]


def described(config: zenoh.Config) -> tuple[str, list[str], list[str]]:
    """The mode a made config opens in, the endpoints it connects to and those it listens on
    (Zenoh keeps an endpoint list per mode where its defaults differ by mode)."""
    mode = json.loads(config.get_json("mode")) or "peer"  # Zenoh's own default

    def endpoints(key: str) -> list[str]:
        value = json.loads(config.get_json(f"{key}/endpoints"))
        return list(value.get(mode, []) if isinstance(value, dict) else value)

    return mode, endpoints("connect"), endpoints("listen")


def make_config(file: str | None, pairs: Sequence[tuple[str, str]]) -> zenoh.Config:
    """A `zenoh.Config`; `InvalidSetting` (a ValueError) naming the file or the key Zenoh refuses."""
    try:
        config = zenoh.Config.from_file(file) if file else zenoh.Config()
    except zenoh.ZError as error:
        raise InvalidSetting(f"Zenoh config file {file}: {_reason(error)}") from None
    for key, value in pairs:
        try:
            config.insert_json5(key, value)
        except zenoh.ZError as error:
            raise InvalidSetting(f"Zenoh config {key}={value}: {_reason(error)}") from None
    return config


def _reason(error: zenoh.ZError) -> str:
    """Zenoh's message without the Rust source location it ends with."""
    return str(error).split(" at /")[0].strip()


Declare = Callable[[zenoh.Session], None]
Args = ParamSpec("Args")
_CALLBACKS_DONE_S = 30.0  # how long `close` waits for calls still running (a stall, a busy core)


class Link:
    """One Zenoh session: opened at `start`, or by a thread that tries every `retry_s` seconds
    until it opens. What is declared through `when_open` is declared as soon as it can be.

    zenoh-python runs each Python callback on a `threading.Thread` of its own, started when the
    entity is declared, waiting in Rust for the next event. A thread that takes the GIL back
    after the interpreter began finalising is ended by `pthread_exit`, which cannot unwind
    through Rust: the process aborts (SIGABRT, "FATAL: exception not rethrown") after a clean
    stop. Two things keep that from happening:
    - `close` ends the calls in order: no new callback nor put (both go through `calling`), the
      running ones finished, every entity undeclared, then the session closed (which ends each
      callback thread's wait);
    - every declare runs on a thread that is no daemon (`as_non_daemon`), so the callback
      threads, which inherit that, are none either: the interpreter waits for them at exit
      before it finalises. Declared on a daemon thread (a route's worker making its publisher,
      the opener, discovery), they were daemons, and one still waking from its closed channel
      when the interpreter finalised aborted it (1 stop in 13 under busy cores: issue 40)."""

    def __init__(
        self, config: Callable[[], zenoh.Config], where: str, retry_s: float = 1.0, client: bool = True
    ) -> None:
        self._config = config  # a new Config per attempt: opening consumes it
        self.where = where
        self._client = client
        self._retry_s = retry_s
        self.session: zenoh.Session | None = None
        self._declares: list[Declare] = []
        self._held: list[object] = []  # Zenoh undeclares what is dropped
        self._transports: set[str] = set()
        # Whether a put can leave: a client's only while a Zenoh transport (to its router) is up,
        # a peer's or router's always (it routes by itself; with no one connected, no one subscribed).
        # Asked on every put, so a plain attribute, kept by `_on_transport` (a property's call costs
        # what a put's guard does).
        self.connected = not client
        self._lock = threading.Lock()
        self._stop = threading.Event()
        # Signals `close` when the last call returns, once it is closing.
        # A plain lock taken with `with` in C, and a plain flag: on every put (0.47 us of guard a put
        # against 0.75 us through the condition's own methods and the event's `is_set`).
        self._calls_lock = threading.Lock()
        self._calls = threading.Condition(self._calls_lock)
        # One item per callback or put inside now: a list's append and pop are each one step under
        # the GIL, where a counter's `+= 1` is three and would need a lock around it per call.
        self._running: list[None] = []
        self._closing = False  # set by `close`: no callback nor put starts after it
        self._thread = threading.Thread(target=self._keep_opening, name="zenoh open", daemon=True)

    def hold(self, handle: object) -> None:
        with self._lock:
            self._held.append(handle)

    def calling(self, call: Callable[Args, None]) -> Callable[Args, None]:
        """`call` guarded: not made at all once `close` began, and counted while it runs, so that
        `close` can wait for it. For callbacks (Zenoh calls them) and for puts (a thread of ours
        calls into Zenoh with the GIL released, and must be out before the interpreter exits)."""

        running = self._running

        def guarded(*args: Args.args, **kwargs: Args.kwargs) -> None:
            # Counted before `_closing` is read: `close` sets it, then waits for none to be counted,
            # so a call either sees it set or is waited for. Once per message: no lock taken.
            running.append(None)
            try:
                if not self._closing:
                    call(*args, **kwargs)
            finally:
                running.pop()
                if self._closing and not running:  # only `close` waits for this
                    with self._calls:
                        self._calls.notify_all()

        return guarded

    def putting(self, put: Callable[..., None]) -> Callable[[bytes, bytes | None], None]:
        """A publisher's `put` guarded as `calling` guards a callback, called with the payload and
        its attachment (or None) as they are: no tuple or dict of arguments made per message."""

        running = self._running

        def guarded(payload: bytes, attachment: bytes | None = None) -> None:
            running.append(None)  # as in `calling`
            try:
                if not self._closing:
                    if attachment is None:
                        put(payload)
                    else:
                        put(payload, attachment=attachment)
            finally:
                running.pop()
                if self._closing and not running:
                    with self._calls:
                        self._calls.notify_all()

        return guarded

    def when_open(self, declare: Declare) -> None:
        """Run `declare(session)` now if the session is open, else once it opens."""
        with self._lock:
            if self.session is None:
                self._declares.append(declare)
                return
            session = self.session
        self._run(declare, session)

    def start(self) -> None:
        if not self._try_open():
            self._thread.start()

    def _keep_opening(self) -> None:
        attempts = 1
        while not self._stop.wait(self._retry_s) and not self._try_open(log=attempts % 60 == 0):
            attempts += 1

    def _try_open(self, log: bool = True) -> bool:
        try:
            session = zenoh.open(self._config())
        except zenoh.ZError as error:
            if log:
                _log.warning("Zenoh: no session yet at %s (%s); trying again every %.0f s",
                             self.where, _reason(error), self._retry_s)  # fmt: skip
            return False
        listener = as_non_daemon(
            lambda: session.info.declare_transport_events_listener(
                self.calling(self._on_transport), history=True
            )
        )
        with self._lock:  # `close` sets the stop before it takes the session under this lock
            closed = self._stop.is_set()
            if not closed:
                self.session = session
                self._held.append(listener)
                declares, self._declares = self._declares, []
        if closed:  # closed while this attempt was under way: the session is no one's to close but ours
            _undeclare(listener)
            session.close()  # type: ignore[no-untyped-call]
            return True
        for declare in declares:
            self._run(declare, session)
        _log.info("Zenoh: session %s open at %s", session.zid(), self.where)
        return True

    def _on_transport(self, event: zenoh.TransportEvent) -> None:
        zid = str(event.transport.zid)
        if event.kind == zenoh.SampleKind.PUT:
            self._transports.add(zid)
        else:
            self._transports.discard(zid)
        self.connected = bool(self._transports) or not self._client

    def _run(self, declare: Declare, session: zenoh.Session) -> None:
        try:
            as_non_daemon(lambda: declare(session))
        except zenoh.ZError as error:  # a key Zenoh refuses: that entity is missing, the rest works
            _log.warning("Zenoh: cannot declare on %s: %s", self.where, error)

    def close(self) -> None:
        """Stop calling, let the running callbacks and puts finish, undeclare, close the session."""
        self._closing = True  # no callback nor put starts after this
        self._stop.set()
        # an attempt under way: a daemon left inside `zenoh.open` at exit would abort it
        if self._thread.is_alive():
            self._thread.join(timeout=_CALLBACKS_DONE_S)
        with self._calls:
            if not self._calls.wait_for(lambda: not self._running, timeout=_CALLBACKS_DONE_S):
                _log.warning(
                    "Zenoh: %d callbacks or puts still running at close (%s)", len(self._running), self.where
                )
        with self._lock:
            session, self.session = self.session, None
            held, self._held = self._held, []
        try:
            for handle in reversed(held):  # explicitly, not whenever the garbage collector drops them
                _undeclare(handle)
        finally:  # whatever else failed: the session's close ends every callback thread's wait
            if session is not None:
                session.close()  # type: ignore[no-untyped-call]


Done = TypeVar("Done")


def as_non_daemon(work: Callable[[], Done]) -> Done:
    """`work()`, on this thread unless it is a daemon, else on a thread that is not, waited for.

    A thread inherits its daemon flag from the thread that starts it, and zenoh-python starts
    the thread that delivers a callback inside the call that declares it."""
    if not threading.current_thread().daemon:
        return work()
    done: list[Done] = []
    failed: list[BaseException] = []

    def run() -> None:
        try:
            done.append(work())
        except BaseException as error:  # raised again on the caller's thread
            failed.append(error)

    helper = threading.Thread(target=run, name="zenoh declare", daemon=False)
    helper.start()
    helper.join()
    if failed:
        raise failed[0]
    return done[0]


def _undeclare(handle: object) -> None:
    undeclare = getattr(handle, "undeclare", None)
    if undeclare is None:
        return
    try:
        undeclare()
    except zenoh.ZError as error:  # e.g. the router gone meanwhile: closing the session ends it anyway
        _log.debug("Zenoh: undeclaring %r at close: %s", handle, error)
    # in use on another thread ("Already borrowed"): the session's close ends it
    except RuntimeError as error:
        _log.warning("Zenoh: undeclaring %r at close: %s", handle, error)
