"""Director's remote tree viewer, both sides: served (requests -> markers) and driven (Drake -> requests)."""

from __future__ import annotations

import re
from typing import Any

from viewer_bridge.errors import DecodeError, RequestRejected, SceneError
from viewer_bridge.formats.ros.markers import marker_array_cdr
from viewer_bridge.formats.ros.message_types import MARKER_ARRAY
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.formats.tree_viewer.requests import (
    DEFAULT_PREFIX,
    SettransformEncoder,
    link_path,
    load_requests,
)
from viewer_bridge.formats.tree_viewer.tree import TreeState
from viewer_bridge.lcmcodec.codecs import VIEWER2_COMMS
from viewer_bridge.model.scene import LinkPoses, Scene
from viewer_bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from viewer_bridge.translators.drake_stream import DrakeTranslator
from viewer_bridge.translators.options import MarkerOptions
from viewer_bridge.translators.types import DRAW_TYPE, ENVELOPE_TYPE, LOAD_TYPE, ros_type
from viewer_bridge.transports.base import Received


class TreeViewerServerOptions(MarkerOptions):
    mesh_roots: list[str] = []  # folders a mesh_file may be in (none: no mesh files)


class TreeViewerServer(Translator):
    """Director's tree viewer, served: requests on `DIRECTOR_TREE_VIEWER_REQUEST_<id>` -> a tree per
    client, answered on `DIRECTOR_TREE_VIEWER_RESPONSE_<id>`, and the tree as a MarkerArray.

    Every request gets exactly one reply: 0, 1 (MISSING_PATHS), -1 (format, listing the one we
    speak), -2 (version), -3 (bad request, or not an envelope at all), -4 (unknown command).
    """

    Options = TreeViewerServerOptions
    options: TreeViewerServerOptions
    reads = (ENVELOPE_TYPE,)
    outputs = (Output("", ros_type(MARKER_ARRAY), latched=True),)
    replies = ENVELOPE_TYPE
    _CLIENT = re.compile(r"DIRECTOR_TREE_VIEWER_REQUEST_<([^<>]*)>")

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.trees: dict[str, TreeState] = {}

    def translate(self, message: Received) -> Outputs:
        match = self._CLIENT.fullmatch(message.channel)
        if match is None:
            raise DecodeError(
                VIEWER2_COMMS.type_name, "", 0, f"{message.channel} is not a tree viewer request channel"
            )
        client = match.group(1)
        state = self.trees.setdefault(client, TreeState(self.options.mesh_roots))
        answer = envelope.response_channel(client)
        try:
            response, changed = self._respond(state, message.data)
        except Exception as error:  # a bug of ours: still answer, then let the router count it
            self.reply(
                answer,
                envelope.encode({"status": envelope.ERROR_HANDLING_REQUEST, "error": repr(error)}),
            )
            raise
        self.reply(answer, envelope.encode(response))
        if response["status"] not in (envelope.OK, envelope.MISSING_PATHS):
            raise RequestRejected(response["status"], f"client {client}: {response['error']}")
        return [(0, marker_array_cdr(state.scene(), self.options.table_overrides(), delete_all=changed))]

    @staticmethod
    def _respond(state: TreeState, data: bytes) -> tuple[dict[str, Any], bool]:
        """The response to one envelope, and whether the tree's geometry changed."""
        try:
            request = envelope.decode(data)
        except RequestRejected as error:
            response: dict[str, Any] = {"status": error.status, "error": str(error)}
            if error.status == envelope.ERROR_UNKNOWN_FORMAT:
                response["supported_formats"] = {envelope.FORMAT: [list(envelope.VERSION)]}
            return response, False
        except DecodeError as error:
            return {"status": envelope.ERROR_HANDLING_REQUEST, "error": str(error)}, False
        changed = bool(request.get("setgeometry") or request.get("delete"))
        return state.respond(request), changed


class TreeViewerClientOptions(TranslatorOptions):
    prefix: list[str] = list(DEFAULT_PREFIX)  # where the scene hangs in the viewer's tree


class DrakeToTreeViewer(DrakeTranslator):
    """Drake load/draw -> tree viewer requests for a running Director (the client side).

    Route the client's response channel to it as well: on MISSING_PATHS it re-sends the geometry
    and transforms under the missing paths; on -1 or -2 (the viewer does not speak our format)
    it says so and stops sending.
    """

    Options = TreeViewerClientOptions
    options: TreeViewerClientOptions
    reads = (LOAD_TYPE, DRAW_TYPE, ENVELOPE_TYPE)
    outputs = (Output("", ENVELOPE_TYPE),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.prefix = tuple(self.options.prefix)
        self.refused: str | None = None
        self.poses: LinkPoses | None = None
        self.settransform = SettransformEncoder(self.prefix)

    def translate(self, message: Received) -> Outputs:
        if self.refused is not None:
            raise SceneError(self.refused)
        if message.data[:8] == VIEWER2_COMMS.packed_fingerprint:
            return self._on_response(envelope.decode(message.data))
        scene, poses = self.drake.read(message)
        out: Outputs = []
        if scene is not None:
            out += [(0, envelope.encode(request)) for request in load_requests(scene, self.prefix)]
        if poses is not None:
            self.poses = poses
            out.append((0, self.settransform.encode(poses)))
        return out

    def _on_response(self, response: dict[str, Any]) -> Outputs:
        status = response.get("status")
        if status in (envelope.ERROR_UNKNOWN_FORMAT, envelope.ERROR_UNKNOWN_FORMAT_VERSION):
            self.refused = (
                f"the viewer refused {envelope.FORMAT} {envelope.VERSION[0]}.{envelope.VERSION[1]} "
                f"(status {status}: {response.get('error', 'no reason given')}); no longer sending to it"
            )
            raise SceneError(self.refused)
        scene = self.drake.scene
        if status != envelope.MISSING_PATHS or scene is None:
            return []
        missing = [tuple(path) for path in response.get("missing_paths", []) if isinstance(path, list)]
        links = tuple(
            link
            for link in scene.links
            if any(_related(tuple(link_path(link, self.prefix)), path) for path in missing)
        )
        if not links:
            return []
        partial = Scene(links, self.poses)
        request = load_requests(partial, self.prefix)[1]  # setgeometry (+ transforms), no delete
        return [(0, envelope.encode(request))]


def _related(link: tuple[str, ...], missing: tuple[Any, ...]) -> bool:
    """Whether a link lies under a missing path, or the missing path under the link."""
    shorter = min(len(link), len(missing))
    return link[:shorter] == tuple(missing[:shorter])
