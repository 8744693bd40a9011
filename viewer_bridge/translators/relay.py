"""Raw LCM relayed as it is: the bytes of any message, unchanged, onto another transport's channel."""

from __future__ import annotations

from viewer_bridge.translators.base import Output, Outputs, Translator
from viewer_bridge.transports.base import LCM, MessageType, Received

ANY_LCM = MessageType("*", LCM)


class LcmRelay(Translator):
    """Any LCM message -> the same bytes: how two LCM buses are joined through another transport
    (a Zenoh router, for one), with a route's channel regex and rate policy. A source `(.*)` and
    a destination `{1}` keep each channel's name (a stream per channel: the router keeps one per
    set of captured groups)."""

    reads = (ANY_LCM,)
    outputs = (Output("", ANY_LCM),)
    relays = True

    def translate(self, message: Received) -> Outputs:
        return [(0, message.data)]
