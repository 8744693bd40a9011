"""What the transports and translators of one router share, made by the router and handed to each.

`Shared` sits below both transports and the router: a transport takes it in `Transport.create`,
a translator in its constructor, and neither needs to know what the others keep in it. It holds
four things of its own, none specific to Drake: the receive time of the message whose outputs
are being published (`MessageTime`), the bridge's one clock (`Clock`: receive or sim time, what
every stamp and log time is), the LCM types the router knows,
and the ROS 2 interface definitions the ros transport may build packages from. Everything else
is opaque here: what the router's config decides (its `CommandPolicy`, a `LoadCache` with its
folder, the `Timelines` that `viewer-bridge play` plays) is given when the `Shared` is made and
read with `Shared.given(kind)`, which names a kind it was not given; what needs no config (one
Foxglove context for the live server and an MCAP file, the draw decoders) is made once per router
by whoever asks first, through `Shared.get(make)`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Literal, Protocol, TypeVar, cast

from viewer_bridge.errors import NotGiven

if TYPE_CHECKING:
    from viewer_bridge.lcmcodec.library import TypeLibrary


class Timed(Protocol):
    """What `MessageTime` reads of a received message (a transport's `Received`, from a layer above)."""

    @property
    def received_us(self) -> int: ...

    @property
    def channel(self) -> str: ...


class MessageTime(threading.local):
    """The receive time (microseconds) of the message whose outputs this thread publishes.

    The router sets `message` before it publishes a translation's outputs (one store per message:
    a thread-local's stores are dear), so a transport that stamps what it writes (an MCAP file's
    log time) gives every output its message's receive time: the log's own time offline, the
    bus's receive time live. One per router; each thread sees its own. `channel` is that message's
    channel on its source (the loop guard remembers where a payload it sends came from:
    `viewer_bridge.router.echoes`).
    """

    message: Timed | None = None

    @property
    def received_us(self) -> int:
        return 0 if self.message is None else self.message.received_us

    @property
    def channel(self) -> str:
        return "" if self.message is None else self.message.channel


TimeSource = Literal["receive", "sim"]
"""The config's `time:`: what every output of the bridge is stamped with."""


class Clock:
    """The bridge's one clock (the config's `time:`), for every output's stamps and log times.

    `receive` (the default): each output carries the receive time of the message it was made
    from, the wall clock that RViz and tf2 expect of a node without `use_sim_time`. `sim`: Drake's
    sim time; a draw carries its own, and everything else (an MCAP file's or Foxglove's log time
    for a load, any LCM type's message) the clock's `now_ns`: the sim time of the newest draw
    received (`tick`, from the router's one decoding of each draw). Listeners (the Foxglove
    server's time broadcast) hear each new time. A draw received before the newest one (a route
    that lags) never moves the clock back; a newer draw with an earlier time does: a restarted
    simulation, which RViz and Foxglove must see as a jump back.
    """

    def __init__(self, time: TimeSource = "receive") -> None:
        self.time: TimeSource = time
        self.sim = time == "sim"
        self.now_ns = 0  # the newest draw's sim time (sim), 0 before the first
        self._received_us = -1  # when that draw was received
        self._listeners: list[Callable[[int], None]] = []
        self._lock = threading.Lock()  # ticked on the routes' threads

    def tick(self, sim_ns: int, received_us: int) -> None:
        """A draw of sim time `sim_ns` received at `received_us`: the clock's time when it is the newest."""
        if not self.sim:
            return
        with self._lock:
            if received_us < self._received_us:
                return
            self._received_us = received_us
            if sim_ns == self.now_ns:
                return
            self.now_ns = sim_ns
            listeners = tuple(self._listeners)
        for listener in listeners:
            listener(sim_ns)

    def log_time_ns(self, received_us: int) -> int:
        """The log time of an output of a message received at `received_us` (an MCAP file's, Foxglove's)."""
        return self.now_ns if self.sim else received_us * 1000

    def listen(self, listener: Callable[[int], None]) -> None:
        """Have `listener(sim_ns)` called with each new time (only with `time: sim`)."""
        with self._lock:
            self._listeners.append(listener)

    def unlisten(self, listener: Callable[[int], None]) -> None:
        with self._lock:
            if listener in self._listeners:
                self._listeners.remove(listener)


Made = TypeVar("Made")


RosDefinitions = Callable[[str], Mapping[str, str]]
"""`ros_definitions(package)`: the ROS 2 `.msg` definitions ("pkg/msg/Name" -> text) of the interface
package `package` and of every package its types use (more is fine), or an empty mapping when it
knows no such package. The ros transport builds a package it lacks from them (the router's LCM
types give theirs: `definitions_of`)."""


def definitions_of(lcm_types: TypeLibrary) -> RosDefinitions:
    """The `RosDefinitions` of a type library: all of its definitions, worked out on the first ask."""
    made: dict[str, str] = {}

    def definitions(package: str) -> Mapping[str, str]:
        if not made:
            made.update(lcm_types.ros_definitions())
        return made

    return definitions


class Shared:
    """What the transports and translators of one router share: the `MessageTime`, its `Clock`
    (the config's `time:`), the LCM types
    it knows (`lcm_types`, loaded once at start from the config's `lcm_types`), the definitions of
    the ROS 2 interface packages that may be built while it runs (`ros_definitions`, or None), and
    what its maker `given` it (`given(LoadCache)`: every route's last Drake load, kept in the
    config's folder; `given(CommandPolicy)`: the channels commands may write), and whatever is made
    once per router on first ask (`get(FoxgloveContext)`: the live server and an MCAP file log to
    one). Two routers share nothing."""

    def __init__(
        self,
        lcm_types: TypeLibrary | None = None,
        ros_definitions: RosDefinitions | None = None,
        time: TimeSource = "receive",
        given: Iterable[object] = (),
    ) -> None:
        self.message_time = MessageTime()
        self.clock = Clock(time)
        self._lcm_types = lcm_types
        self.ros_definitions = ros_definitions
        self._given = {type(made): made for made in given}  # by class: one of each
        self._made: dict[Callable[..., object], object] = {}
        self._lock = threading.Lock()  # translators are made on the routes' threads

    @property
    def lcm_types(self) -> TypeLibrary:
        """The router's known LCM types (without a router: the project's and Drake's, loaded on first ask)."""
        if self._lcm_types is None:
            from viewer_bridge.lcmcodec.library import TypeLibrary  # numpy and rosbags: only when asked

            self._lcm_types = TypeLibrary.load()
        return self._lcm_types

    def get(self, make: Callable[..., Made], *arguments: object) -> Made:
        """This router's one `make(*arguments)`, made on the first ask (later asks' arguments unused)."""
        with self._lock:
            if make not in self._made:
                self._made[make] = make(*arguments)
            return cast(Made, self._made[make])

    def given(self, kind: type[Made]) -> Made:
        """The `kind` this `Shared` was given when it was made; `NotGiven` when it was given none
        (no default is guessed: a router gives what its config decides)."""
        if kind not in self._given:
            raise NotGiven(
                f"this Shared was given no {kind.__name__} when it was made (Shared(..., given=[...]))"
            )
        return cast(Made, self._given[kind])
