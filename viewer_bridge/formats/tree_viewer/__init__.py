"""Director's remote tree viewer protocol (`treeviewer_json` 1.0; docs/PROTOCOLS.md section 2).

Requests are JSON objects with `setgeometry`, `settransform` and `delete` command lists, carried
in a `robotlocomotion.viewer2_comms_t` on `DIRECTOR_TREE_VIEWER_REQUEST_<client_id>`.
`envelope`: that envelope, the response status codes and the channel names; `requests`: a scene
as requests (a load, a draw); `tree`: requests applied to a tree, answered as Director does and
read back as a scene, with `commands` reading the geometry and transform objects in them;
`common`: what they all share (the JSON object type, where a scene hangs in the tree).
"""
