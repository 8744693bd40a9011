"""What the tree viewer's modules share: the JSON object type and where a scene hangs in the tree.

Kept free of imports: the facade (`viewer_bridge.convert`) names these at its own import.
"""

DEFAULT_PREFIX: tuple[str, ...] = ("drake",)  # where a scene hangs in the viewer's tree

JsonObject = dict[str, object]
"""A JSON object (a request as the tree viewer is sent it, its response): values are str, int,
float, bool, None, and lists and objects of them. Typed `object` rather than as a recursive
union, which `typing.get_type_hints` cannot resolve outside this module."""
