"""Drake's contact results (`CONTACT_RESULTS`, `lcmt_contact_results_for_viz`) to ROS 2, ign and Director.

`drake_contacts_to_marker_array`: a MarkerArray per message (arrows, pressure-coloured
surfaces; see `viewer_bridge.model.contact` for the drawing options), latched like the scene's markers.
`drake_contacts_to_wrenches`: a `geometry_msgs/WrenchStamped` per contact pair, all on the one
destination topic. `drake_contacts_to_ign_contacts`: ign/gz `Contacts`.
`drake_contacts_to_tree_viewer`: requests for Director's tree viewer (arrows as `line`s with a
head). All decode a message once between them (`contact_results`).
"""

from __future__ import annotations

from typing import Any

from viewer_bridge.formats.drake.contact import decode_contact_results
from viewer_bridge.formats.ign.contact import contacts_message
from viewer_bridge.formats.ros.contact import WrenchEncoder, contact_marker_array_cdr
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY, WORLD, WRENCH_STAMPED
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.formats.tree_viewer.requests import load_requests
from viewer_bridge.model.contact import ContactDrawOptions, ContactResults, contact_scene
from viewer_bridge.model.sim_time import sec_nsec_from_us
from viewer_bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from viewer_bridge.translators.options import IgnOptions, MarkerOptions, StampOptions
from viewer_bridge.translators.types import CONTACT_TYPE, ENVELOPE_TYPE, ign_type, ros_type
from viewer_bridge.transports.base import Received


def _decode(message: Received) -> ContactResults:
    return decode_contact_results(message.data)


def contact_results(message: Received) -> ContactResults:
    """A received `lcmt_contact_results_for_viz`, decoded once for every route that reads it."""
    return message.decoded(_decode)


class ContactMarkerOptions(MarkerOptions, ContactDrawOptions):
    """How contacts are drawn (`viewer_bridge.model.contact.ContactDrawOptions`) and the marker table's options."""


class DrakeContactsToMarkerArray(Translator):
    """contact results -> `MarkerArray` (DELETEALL, an ARROW per force and moment, a
    TRIANGLE_LIST per hydroelastic surface coloured by pressure). Latched."""

    Options = ContactMarkerOptions
    options: ContactMarkerOptions
    reads = (CONTACT_TYPE,)
    outputs = (Output("", ros_type(MARKER_ARRAY), latched=True),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._markers = self.options.table_overrides()

    def translate(self, message: Received) -> Outputs:
        return [(0, contact_marker_array_cdr(contact_results(message), self.options, self._markers))]


class WrenchOptions(StampOptions):
    frame_id: str = WORLD  # the wrenches' axes: Drake's world frame


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
        sim = self.options.sim_stamps(self.shared.clock)
        time_us = results.timestamp_us if sim else message.received_us
        return [(0, data) for data in self.encoder.encode(results, sec_nsec_from_us(time_us))]


class IgnContactOptions(IgnOptions):
    world: str = WORLD  # the name of the `world` entity in every Contact


class DrakeContactsToIgnContacts(Translator):
    """contact results -> ign/gz `Contacts`: a Contact per pair."""

    Options = IgnContactOptions
    options: IgnContactOptions
    reads = (CONTACT_TYPE,)
    outputs = (Output("", ign_type("Contacts")),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.outputs = (Output("", self.options.message_type("Contacts")),)

    def translate(self, message: Received) -> Outputs:
        contacts = contacts_message(contact_results(message), self.options.world)
        return [(0, contacts.SerializeToString())]


class ContactTreeViewerOptions(TranslatorOptions, ContactDrawOptions):
    prefix: list[str] = ["contacts"]  # where the contacts hang in the viewer's tree


class DrakeContactsToTreeViewer(Translator):
    """contact results -> tree viewer requests for a running Director: the old contacts deleted,
    then a `line` with an arrowhead per force and moment, a `mesh_data` per surface (one colour:
    the pressure map's colour at the surface's mean pressure; Director has no vertex colours)."""

    Options = ContactTreeViewerOptions
    options: ContactTreeViewerOptions
    reads = (CONTACT_TYPE,)
    outputs = (Output("", ENVELOPE_TYPE),)

    def translate(self, message: Received) -> Outputs:
        results = contact_results(message)
        requests = load_requests(
            contact_scene(results, self.options), self.options.prefix, results.timestamp_us
        )
        return [(0, envelope.encode(request)) for request in requests]
