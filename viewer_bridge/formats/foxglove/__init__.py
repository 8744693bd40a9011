"""Foxglove's messages (foxglove-schemas-protobuf), one module per message family: the scene as
`foxglove.SceneUpdate` (`scene`), a draw as `foxglove.FrameTransforms` (`transforms`), and the
schemas channels and MCAP files carry (`schema`, the one module a transport may use)."""
