"""Drake's contact results (`CONTACT_RESULTS`, `lcmt_contact_results_for_viz`) to ROS 2.

`drake_contacts_to_marker_array`: a MarkerArray per message (arrows, pressure-coloured
surfaces; see `bridge.contact` for the drawing options), latched like the scene's markers.
`drake_contacts_to_wrenches`: a `geometry_msgs/WrenchStamped` per contact pair, all on the one
destination topic. Both decode a message once between them (`contact_results`).
"""

from __future__ import annotations

from typing import Any, Literal

from bridge.contact import ContactDrawOptions, ContactResults
from bridge.formats import ros
from bridge.formats.drake_contact import decode_contact_results
from bridge.formats.ros_contact import WRENCH_STAMPED, WrenchEncoder, contact_marker_array_cdr
from bridge.formats.ros_tf import WORLD
from bridge.lcmcodec import CONTACT_RESULTS
from bridge.sim_time import sec_nsec_from_us
from bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from bridge.translators.drake_ros import MarkerOptions, ros_type
from bridge.transports.base import LCM, MessageType, Received

CONTACT_TYPE = MessageType(CONTACT_RESULTS.type_name, LCM)


def _decode(message: Received) -> ContactResults:
    return decode_contact_results(message.data)


def contact_results(message: Received) -> ContactResults:
    """A received `lcmt_contact_results_for_viz`, decoded once for every route that reads it."""
    return message.decoded(_decode)


class ContactMarkerOptions(ContactDrawOptions, MarkerOptions):
    """How contacts are drawn (`bridge.contact.ContactDrawOptions`) and the marker table's options."""

    def marker_overrides(self) -> dict[str, Any]:
        return MarkerOptions.model_validate(
            self.model_dump(include=set(MarkerOptions.model_fields))
        ).table_overrides()


class DrakeContactsToMarkerArray(Translator):
    """contact results -> `MarkerArray` (DELETEALL, an ARROW per force and moment, a
    TRIANGLE_LIST per hydroelastic surface coloured by pressure). Latched."""

    Options = ContactMarkerOptions
    options: ContactMarkerOptions
    reads = (CONTACT_TYPE,)
    outputs = (Output("", ros_type(ros.MARKER_ARRAY), latched=True),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._markers = self.options.marker_overrides()

    def translate(self, message: Received) -> Outputs:
        return [(0, contact_marker_array_cdr(contact_results(message), self.options, self._markers))]


class WrenchOptions(TranslatorOptions):
    frame_id: str = WORLD  # the wrenches' axes: Drake's world frame
    stamp: Literal["receive", "sim"] = "receive"  # sim: Drake's sim time (for use_sim_time nodes)


class DrakeContactsToWrenches(Translator):
    """contact results -> a `WrenchStamped` per contact pair (point contacts, then hydroelastic)."""

    Options = WrenchOptions
    options: WrenchOptions
    reads = (CONTACT_TYPE,)
    outputs = (Output("", ros_type(WRENCH_STAMPED)),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.encoder = WrenchEncoder(self.options.frame_id)

    def translate(self, message: Received) -> Outputs:
        results = contact_results(message)
        time_us = results.timestamp_us if self.options.stamp == "sim" else message.received_us
        return [(0, data) for data in self.encoder.encode(results, sec_nsec_from_us(time_us))]
