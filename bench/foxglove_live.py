"""Benchmark: draw -> foxglove.FrameTransforms bytes, beside the foxglove-sdk's own classes.

Run: .venv/bin/python bench/foxglove_live.py [--links 1000] [--budget 0.5]

Ours: `lcmt_viewer_draw` bytes -> `DrawDecoder` -> `FrameTransformsEncoder` (a per-name-set
protobuf wire template; numpy scatters the doubles and the stamp). Baseline: the SDK's way, a
`foxglove.messages.FrameTransform` built per link from the same decoded arrays, then
`FrameTransforms.encode()`. Both parse to the same `foxglove.FrameTransforms` (checked). Also the
once-per-load SceneUpdate of a 1000-geometry scene.
"""

from __future__ import annotations

import argparse

from draw_codec import frame, seconds_per_call  # bench/ is on sys.path when run as a script
from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms as FrameTransformsProto
from translators import scene

from bridge.formats import foxglove
from bridge.formats.drake import DrawDecoder, DrawEncoder
from bridge.formats.ros_tf import FrameNames
from bridge.scene import LinkPoses


def sdk_frame_transforms(poses: LinkPoses, stamp: tuple[int, int], frames: FrameNames) -> bytes:
    """The baseline: the SDK's FrameTransform objects, one per link, then its encoder."""
    timestamp = Timestamp(sec=stamp[0], nsec=stamp[1])
    transforms = [
        FrameTransform(
            timestamp=timestamp,
            parent_frame_id=frames.world_frame,
            child_frame_id=frames(name),
            translation=Vector3(x=position[0], y=position[1], z=position[2]),
            rotation=Quaternion(x=x, y=y, z=z, w=w),
        )
        for name, position, (w, x, y, z) in zip(
            poses.names, poses.positions.tolist(), poses.quaternions_wxyz.tolist(), strict=True
        )
    ]
    return bytes(FrameTransforms(transforms=transforms).encode())


def parsed(data: bytes) -> FrameTransformsProto:
    message = FrameTransformsProto()
    message.ParseFromString(data)
    return message


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--links", type=int, default=1000)
    parser.add_argument("--budget", type=float, default=0.5, help="seconds per measurement")
    args = parser.parse_args()

    draw = DrawEncoder().encode(frame(args.links))
    decoder, frames = DrawDecoder(), FrameNames()
    encoder = foxglove.FrameTransformsEncoder(frames)
    stamp = (61, 250_000_000)

    def ours() -> bytes:
        return encoder.encode(decoder.decode(draw), stamp)

    def baseline() -> bytes:
        return sdk_frame_transforms(decoder.decode(draw), stamp, frames)

    assert parsed(ours()) == parsed(baseline())
    fast, slow = seconds_per_call(ours, args.budget), seconds_per_call(baseline, args.budget)
    print(f"draw -> foxglove.FrameTransforms bytes, {args.links} links (from lcmt_viewer_draw bytes)")
    print(f"  viewer-bridge wire template              {fast * 1e6:10.1f} us")
    print(f"  foxglove-sdk FrameTransform one by one   {slow * 1e6:10.1f} us")
    print(f"  ratio                                    {slow / fast:10.0f}x")

    load = scene(args.links)
    once = seconds_per_call(lambda: foxglove.scene_update(load, frames).SerializeToString(), args.budget)
    print(f"\nload -> foxglove.SceneUpdate bytes, {load.geometry_count()} geometries: {once * 1e3:.2f} ms (once per load)")


if __name__ == "__main__":
    main()
