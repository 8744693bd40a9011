"""Benchmark: draw -> tf2_msgs/TFMessage CDR, beside the rclpy way, in this process.

Run: .venv/bin/python bench/tf.py [--links 1000] [--budget 0.5]
(bench/all.py takes the same figures as rows, `measures`: quick times them shorter, smoke at 10 links.)

Ours: `lcmt_viewer_draw` bytes -> `DrawDecoder` -> `TransformsEncoder` (a per-name-set CDR
template, numpy writes the stamps and the doubles). Baseline: one `TransformStamped` built per
link from the same decoded arrays, then `rclpy.serialization.serialize_message`. Both decode to
the same message (checked). Also: the once-per-load MarkerArray in link frames, beside the
world-frame array a draw re-poses every frame (`MarkerStream.update`), which the link frames
replace.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from common import Measure, Size, frame  # bench/ is on sys.path when run as a script
from draw_codec import seconds_per_call
from geometry_msgs.msg import Quaternion, TransformStamped, Vector3
from rclpy.serialization import deserialize_message, serialize_message
from tf2_msgs.msg import TFMessage
from translators import scene

from viewer_bridge.formats.drake.draw import DrawDecoder, DrawEncoder
from viewer_bridge.formats.ros.markers import MarkerStream, marker_array_in_link_frames_cdr
from viewer_bridge.formats.ros.tf import FrameNames, TransformsEncoder
from viewer_bridge.model.scene import LinkPoses


def rclpy_tf(poses: LinkPoses, stamp: tuple[int, int], frames: FrameNames) -> bytes:
    """The baseline: a TransformStamped per link, built as rclpy users do, then serialised."""
    message = TFMessage()
    transforms = []
    for name, position, (w, x, y, z) in zip(
        poses.names, poses.positions.tolist(), poses.quaternions_wxyz.tolist(), strict=True
    ):
        transform = TransformStamped()
        transform.header.stamp.sec, transform.header.stamp.nanosec = stamp
        transform.header.frame_id = frames.world_frame
        transform.child_frame_id = frames(name)
        transform.transform.translation = Vector3(x=position[0], y=position[1], z=position[2])
        transform.transform.rotation = Quaternion(x=x, y=y, z=z, w=w)
        transforms.append(transform)
    message.transforms = transforms
    return bytes(serialize_message(message))


class Cases:
    """What each figure times, for a draw of `links` links: ours, its rclpy baseline, and the
    world-frame and link-frame marker set-ups (`MarkerStream.update` every draw; the MarkerArray in
    link frames, once per load)."""

    def __init__(self, links: int) -> None:
        draw = DrawEncoder().encode(frame(links))
        decoder, frames = DrawDecoder(), FrameNames()
        encoder = TransformsEncoder(frames)
        stamp = (1_700_000_000, 250_000_000)
        self.ours: Callable[[], bytes] = lambda: encoder.encode(decoder.decode(draw), stamp)
        self.baseline: Callable[[], bytes] = lambda: rclpy_tf(decoder.decode(draw), stamp, frames)
        assert deserialize_message(self.ours(), TFMessage) == deserialize_message(self.baseline(), TFMessage)
        load = scene(links).with_poses(frame(links))
        stream = MarkerStream(load)
        moved = frame(links, seed=1)
        self.markers = len(stream)
        self.per_draw: Callable[[], object] = lambda: stream.update(moved)
        self.once: Callable[[], object] = lambda: marker_array_in_link_frames_cdr(load, frames)


def measures(size: Size = Size.FULL) -> list[Measure]:
    """draw -> TFMessage CDR beside rclpy (goal 100x), and what link frames cost per draw and per load."""
    links = size.pick(full=1000, quick=1000, smoke=10)
    budget = size.pick(full=0.5, quick=0.2, smoke=0.0)
    cases = Cases(links)
    fast, slow = seconds_per_call(cases.ours, budget), seconds_per_call(cases.baseline, budget)
    per_draw, once = seconds_per_call(cases.per_draw, budget), seconds_per_call(cases.once, budget)
    return [
        Measure(f"draw -> TFMessage CDR, {links} links (from lcmt_viewer_draw bytes), vs rclpy TransformStamped "
                "one by one", fast * 1e6, slow * 1e6, "us", "ratio >= 100x", slow / fast >= 100),
        Measure(f"per draw, {links} links: one TFMessage (link frames), vs MarkerStream.update of its "
                f"{cases.markers} markers (world frame)", fast * 1e6, per_draw * 1e6, "us", "none (reported)", None),
        Measure(f"link frames: the MarkerArray of {cases.markers} markers, once per load", once * 1e3, None, "ms",
                "none (reported)", None),
    ]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--links", type=int, default=1000)
    parser.add_argument("--budget", type=float, default=0.5, help="seconds per measurement")
    args = parser.parse_args()

    cases = Cases(args.links)
    fast, slow = seconds_per_call(cases.ours, args.budget), seconds_per_call(cases.baseline, args.budget)
    print(f"draw -> TFMessage CDR, {args.links} links (from lcmt_viewer_draw bytes)")
    print(f"  viewer-bridge fast path               {fast * 1e6:10.1f} us")
    print(f"  rclpy TransformStamped one by one     {slow * 1e6:10.1f} us")
    print(f"  ratio                                 {slow / fast:10.0f}x   (goal >= 100x)")

    per_draw = seconds_per_call(cases.per_draw, args.budget)
    once = seconds_per_call(cases.once, args.budget)
    print(f"\nper draw, {cases.markers} markers: what the world-frame route does, what the TF set-up does")
    print(f"  world frame: MarkerStream.update every draw    {per_draw * 1e6:10.1f} us")
    print(f"  link frames: one TFMessage every draw          {fast * 1e6:10.1f} us")
    print(f"  link frames: the MarkerArray, once per load    {once * 1e3:10.2f} ms")


if __name__ == "__main__":
    main()
