"""Rerun: Drake's scene, draws, contacts, clouds and images as Rerun chunks (rerun-sdk archetypes).

`schema` (what the rerun transport may import: the message type, as the SDK's chunks and as
bytes), `chunks` (archetypes -> chunks, entity paths, the timelines), then one module per family:
`scene` (a load, by `mappings/rerun.yaml`), `transforms` (a draw, one chunk from the arrays),
`contact`, `point_cloud`, `image`.
"""
