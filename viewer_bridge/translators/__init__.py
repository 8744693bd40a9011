"""The router's translators: one class per (source message, target message) pair.

Grouped by family: `drake_ros` (Drake's LCM scene <-> ROS 2), `drake_tf` (a TF tree and
markers in link frames, the way ROS consumes motion), `drake_foxglove` (Foxglove's SceneUpdate
and FrameTransforms), `drake_point_cloud` (point clouds both ways, DRAKE_DRAW_FRAMES as
triads), `drake_ign` (<-> ign/gz protobuf), `drake_contact` (contact results to all three),
`drake_image` (camera images <-> ROS 2, and to Foxglove), `tree_viewer` (Director's remote tree
viewer, both sides), `drake_rerun` (Rerun's archetypes), `relay` (raw LCM onto another transport,
unchanged), `lcm_generic` (any LCM type as its ROS 2 mapping, and back), `ros_topics` (any ROS 2
topic onto LCM), `lcm_rerun` (any LCM type's numbers as Rerun scalars). Families share only these: `base`
(what a translator is), `types` (the message types, each named once), `options` (options to
inherit: markers, frames, ign names), `drake_stream` (the decode-once draw, and
`DrakeTranslator`, the base that follows Drake's load/draw stream) and `load_cache` (the last
load per channel, kept across restarts); no family imports another.
`registry` holds `TRANSLATORS`, the registry a route's `translator:` word is looked up in.
"""
