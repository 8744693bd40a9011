"""Director's remote tree viewer protocol (`treeviewer_json` 1.0; docs/PROTOCOLS.md section 2).

Requests are JSON objects with `setgeometry`, `settransform` and `delete` command lists, carried
in a `robotlocomotion.viewer2_comms_t` on `DIRECTOR_TREE_VIEWER_REQUEST_<client_id>`.
`envelope`: that envelope, the response status codes and the channel names; `requests`: a scene
as requests (a load, a draw); `tree`: requests applied to a tree, answered as Director does and
read back as a scene, with `commands` reading the geometry and transform objects in them.
"""

# Kept free of imports: the facade (`viewer_bridge.convert`) names these at its own import.

DEFAULT_PREFIX: tuple[str, ...] = ("drake",)  # where a scene hangs in the viewer's tree

JsonObject = dict[str, object]
"""A JSON object (a request as the tree viewer is sent it, its response): values are str, int,
float, bool, None, and lists and objects of them. Typed `object` rather than as a recursive
union, which `typing.get_type_hints` cannot resolve outside this module."""

__all__ = ["DEFAULT_PREFIX", "JsonObject"]
