"""Any LCM type to Rerun: every numeric field of every message as `Scalars`, so each plots with no
configuration (`/lcm/<channel>/<field path>`, the route's destination naming `/lcm/<channel>`).

A message's `utime` (LCM's microseconds, Drake's sim time) places it on the `sim_time` timeline
beside the scene; every message is on `receive_time` too. A channel's type is what its
fingerprint names, per message (as `lcm_to_ros` reads it); an unknown one is held and counted.
"""

from __future__ import annotations

from viewer_bridge.formats.rerun.chunks import Stamp, entity_path, received_chunk, timed_chunk
from viewer_bridge.formats.rerun.scalars import scalars_of, sim_time_us
from viewer_bridge.formats.rerun.schema import Chunks
from viewer_bridge.translators.base import Output, Outputs, Translator
from viewer_bridge.translators.types import ANY_LCM_TYPE, RERUN_CHUNKS_TYPE
from viewer_bridge.transports.base import Received


class LcmToRerunScalars(Translator):
    """Any known LCM type -> one `Scalars` entity per numeric field, at the message's times."""

    reads = (ANY_LCM_TYPE,)
    outputs = (Output("", RERUN_CHUNKS_TYPE),)

    def translate(self, message: Received) -> Outputs:
        lcm_type = self.shared.lcm_types.type_of(message.data, message.channel)
        fields = lcm_type.to_dict(message.data)
        sim_us = sim_time_us(fields)
        parts = [
            received_chunk(entity_path(*path), message.received_us, [scalars])
            if sim_us is None
            else timed_chunk(entity_path(*path), Stamp.of(sim_us, message.received_us), [scalars])
            for path, scalars in scalars_of(fields)
        ]
        return [(0, Chunks.joined(parts))] if parts else []
