"""Benchmark: what the loop guard (viewer_bridge/router/echoes.py) costs a message.

Run: .venv/bin/python bench/loop_guard.py [--quick]

Only a name the router both publishes on and subscribes to is guarded. There, one message costs
a send remembered (`GuardedPublisher.publish`) and its echo recognised and consumed (the guarded
`deliver`): measured for `lcmt_iiwa_status` as CDR (its ROS 2 mapping, what goes out on /X), and
set against what the route does for that message anyway, `lcm_to_ros`'s translation of it; the
goal: under 10 us, 1% of the period of a 1 kHz command stream (Drake's iiwa driver's rate). Every
other name pays one lookup in an empty dict per message delivered: measured as the wrapped
`deliver` against calling the route's `offer` directly. Both sides of a row run in this process,
in alternating rounds.
"""

from __future__ import annotations

import argparse
from functools import partial

from common import Measure, Size  # bench/ is on sys.path when run as a script
from draw_codec import paired, print_measures
from lcm_generic import iiwa_status

from viewer_bridge.lcmcodec.library import TypeLibrary
from viewer_bridge.router.echoes import Echoes
from viewer_bridge.shared import MessageTime
from viewer_bridge.transports.base import CallPublisher, Publisher, Received


def _nothing(_: object) -> None:
    return None


def _guarded_round(publisher: Publisher, deliver: object, cdr: bytes) -> None:
    publisher.publish(cdr)  # remembered
    deliver(Received("/X", cdr))  # type: ignore[operator]  # recognised and consumed


def _plain_round(publisher: Publisher, offer: object, cdr: bytes) -> None:
    publisher.publish(cdr)
    offer(Received("/X", cdr))  # type: ignore[operator]


def measures(size: Size = Size.FULL) -> list[Measure]:
    rows = []
    library = TypeLibrary.load()
    data = iiwa_status().encode()
    known = library.get("drake.lcmt_iiwa_status")
    cdr = known.to_cdr(data)
    sending = MessageTime()
    sending.message = Received("X", data)  # the message whose outputs are sent (what the runner sets)
    echoes = Echoes(sending)
    plain = CallPublisher(_nothing)
    guarded = echoes.publisher("ros", "/X", plain, "lcm", subscribed=True)
    deliver = echoes.deliver("ros", _nothing, lambda message, origin: None)
    guard_cost, plain_cost = paired(
        partial(_guarded_round, guarded, deliver, cdr), partial(_plain_round, plain, _nothing, cdr), size
    )
    translate = paired(partial(known.to_cdr, data), partial(known.to_cdr, data), size)[0]
    added = max(guard_cost - plain_cost, 0.0)
    rows.append(Measure("loop guard, a guarded name: added per message, vs translating it (lcmt_iiwa_status)",
                        added * 1e6, translate * 1e6, "us", "added <= 10 us", added <= 10e-6))  # fmt: skip
    unguarded = Echoes(sending).deliver("lcm", _nothing, lambda message, origin: None)
    message = Received("IIWA_STATUS", data)
    wrapped, direct = paired(partial(unguarded, message), partial(_nothing, message), size)
    rows.append(Measure("loop guard, any other name: deliver, vs calling the route directly", wrapped * 1e6,
                        direct * 1e6, "us", "added < 0.5 us", wrapped - direct < 0.5e-6))  # fmt: skip
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="fewer rounds")
    print_measures(measures(Size.QUICK if parser.parse_args().quick else Size.FULL))


if __name__ == "__main__":
    main()
