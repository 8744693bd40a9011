"""The LCM codecs of the types in `lcmtypes/`, generated from the schemas when first imported.

They come from `serde`'s one registry, as every type store's do: a message of one is a message of
the other (`viewer_bridge.lcm_types().encode(DRAW.decode(data))` works). Like LCM, they pass NaN
and infinities both ways; `codec.strict` is the same codec whose decoder refuses them with a
`DecodeError` naming the field and offset, which the viewer's formats use (a pose, a geometry or a
contact force must be finite).

Usage::

    message = DRAW.decode(data)          # a drake.lcmt_viewer_draw message
    assert DRAW.encode(message) == data  # byte-identical to lcm-gen's output
    DRAW.strict.decode(data)             # the same, or DecodeError for a NaN or infinity
"""

from __future__ import annotations

from viewer_bridge.lcmcodec.codegen import Buffer
from viewer_bridge.lcmcodec.schema import StructDef, load_schema_dir
from viewer_bridge.lcmcodec.serde import LcmMessage, StructCodec, compile_codecs
from viewer_bridge.util.resources import data_dir

SCHEMA_DIR = data_dir("lcmtypes")
STRUCTS: dict[str, StructDef] = load_schema_dir(SCHEMA_DIR)
CODECS: dict[str, StructCodec] = compile_codecs(STRUCTS, finite=False)

LOAD_ROBOT = CODECS["drake.lcmt_viewer_load_robot"]
LINK_DATA = CODECS["drake.lcmt_viewer_link_data"]
GEOMETRY_DATA = CODECS["drake.lcmt_viewer_geometry_data"]
DRAW = CODECS["drake.lcmt_viewer_draw"]
VIEWER2_COMMS = CODECS["robotlocomotion.viewer2_comms_t"]
POINT_CLOUD = CODECS["drake.lcmt_point_cloud"]
POINT_CLOUD_FIELD = CODECS["drake.lcmt_point_cloud_field"]
CONTACT_RESULTS = CODECS["drake.lcmt_contact_results_for_viz"]
HEADER = CODECS["drake.lcmt_header"]
IMAGE = CODECS["drake.lcmt_image"]
IMAGE_ARRAY = CODECS["drake.lcmt_image_array"]

_BY_FINGERPRINT = {codec.packed_fingerprint: codec for codec in CODECS.values()}


def codec_for(data: Buffer) -> StructCodec | None:
    """The codec whose fingerprint starts `data`, or None for a type we have no schema for."""
    return _BY_FINGERPRINT.get(bytes(data[:8]))


__all__ = [
    "CODECS",
    "CONTACT_RESULTS",
    "DRAW",
    "GEOMETRY_DATA",
    "HEADER",
    "IMAGE",
    "IMAGE_ARRAY",
    "LINK_DATA",
    "LOAD_ROBOT",
    "POINT_CLOUD",
    "POINT_CLOUD_FIELD",
    "SCHEMA_DIR",
    "STRUCTS",
    "VIEWER2_COMMS",
    "Buffer",
    "LcmMessage",
    "StructCodec",
    "codec_for",
]
