"""The formats: each ecosystem's messages to and from the neutral model, one folder per ecosystem
(`drake`, `ros`, `ign`, `foxglove`, `tree_viewer`, `rerun`); glTF (`gltf`); and what several share
(`point_fields`, the point layout of Drake's and ROS's clouds; `protowire`, protobuf's wire format)."""
