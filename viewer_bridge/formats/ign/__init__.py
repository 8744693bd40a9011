"""ign-msgs 8 / gz-msgs protobuf: the message schema (`schema`) and the scene to and from it, by
message family: `poses` (Pose_V, PosesStamped), `geometry` (Geometry, with its table in
mappings/ign.yaml), `model` (Model, Model_V) and `contact` (Contacts)."""
