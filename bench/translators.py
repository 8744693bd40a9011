"""Benchmark: the translators' hot and cold paths, each beside a baseline run in this process.

Run: .venv/bin/python bench/translators.py [--links 1000] [--budget 0.3]

* draw -> geometry_msgs/PoseArray CDR. Ours: `lcmt_viewer_draw` bytes -> `DrawDecoder` ->
  `PoseArrayEncoder` (numpy, no message objects). Baseline: the usual rclpy way, one
  `geometry_msgs.msg.Pose` built per link from the same decoded arrays, then
  `rclpy.serialization.serialize_message`.
* draw -> one `PoseStamped` per link, the same way.
* draw -> re-posed MarkerArray (`MarkerStream.update`) against building the MarkerArray anew.
* load (one geometry per link) -> MarkerArray CDR, ign Model bytes, tree viewer JSON envelopes:
  milliseconds, beside the object paths (rosbags messages; protobuf objects).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from draw_codec import frame, seconds_per_call  # bench/ is on sys.path when run as a script
from geometry_msgs.msg import Point, Pose, PoseArray, PoseStamped, Quaternion
from rclpy.serialization import serialize_message

from bridge.formats import ign, ros
from bridge.formats import tree_viewer as tv
from bridge.formats.drake import DrawDecoder, DrawEncoder
from bridge.scene import Box, Capsule, Cylinder, Ellipsoid, Geometry, Link, LinkPoses, Scene, Sphere
from bridge.scene import Pose as ScenePose


def scene(links: int) -> Scene:
    """One primitive per link, cycling through the shapes (a 1000-link load has 1000 geometries)."""
    shapes = [
        Box((0.1, 0.2, 0.3)),
        Sphere(0.05),
        Cylinder(0.04, 0.3),
        Capsule(0.03, 0.2),
        Ellipsoid((0.1, 0.2, 0.3)),
    ]
    names = frame(links).names
    return Scene(
        tuple(
            Link(
                name,
                index % 7,
                (Geometry(shapes[index % len(shapes)], ScenePose((0.1, 0.0, 0.0)), (0.5, 0.5, 0.5, 1.0)),),
            )
            for index, name in enumerate(names)
        )
    )


def rclpy_pose_array(poses: LinkPoses) -> bytes:
    """The baseline: rclpy message objects built one by one, then serialised."""
    message = PoseArray()
    message.header.frame_id = "world"
    seconds, milliseconds = divmod(poses.timestamp_ms, 1000)
    message.header.stamp.sec, message.header.stamp.nanosec = seconds, milliseconds * 1_000_000
    items = []
    for position, (w, x, y, z) in zip(poses.positions.tolist(), poses.quaternions_wxyz.tolist(), strict=True):
        items.append(
            Pose(
                position=Point(x=position[0], y=position[1], z=position[2]),
                orientation=Quaternion(x=x, y=y, z=z, w=w),
            )
        )
    message.poses = items
    return bytes(serialize_message(message))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--links", type=int, default=1000)
    parser.add_argument("--budget", type=float, default=0.3, help="seconds per measurement")
    args = parser.parse_args()
    links = args.links

    draw = DrawEncoder().encode(frame(links))
    decoder, encoder = DrawDecoder(), ros.PoseArrayEncoder("world")
    decoder.decode(draw)  # steady state: the name block is cached after the first frame

    def ours() -> bytes:
        return encoder.encode(decoder.decode(draw))

    def baseline() -> bytes:
        return rclpy_pose_array(decoder.decode(draw))

    from rclpy.serialization import deserialize_message

    assert deserialize_message(ours(), PoseArray) == deserialize_message(baseline(), PoseArray)
    fast, slow = seconds_per_call(ours, args.budget), seconds_per_call(baseline, args.budget)
    print(f"draw -> PoseArray CDR, {links} links (from lcmt_viewer_draw bytes)")
    print(f"  viewer-bridge fast path      {fast * 1e6:10.1f} us")
    print(f"  rclpy objects one by one     {slow * 1e6:10.1f} us")
    print(f"  ratio                        {slow / fast:10.0f}x")

    stamped = ros.PoseStampedEncoder("world")

    def rclpy_pose_stamped() -> list[bytes]:
        poses = decoder.decode(draw)
        out = []
        for position, (w, x, y, z) in zip(
            poses.positions.tolist(), poses.quaternions_wxyz.tolist(), strict=True
        ):
            message = PoseStamped()
            message.header.frame_id = "world"
            message.pose.position = Point(x=position[0], y=position[1], z=position[2])
            message.pose.orientation = Quaternion(x=x, y=y, z=z, w=w)
            out.append(bytes(serialize_message(message)))
        return out

    fast = seconds_per_call(lambda: stamped.encode(decoder.decode(draw)), args.budget)
    slow = seconds_per_call(rclpy_pose_stamped, args.budget)
    print(f"\ndraw -> one PoseStamped CDR per link, {links} links")
    print(f"  viewer-bridge fast path      {fast * 1e6:10.1f} us")
    print(f"  rclpy objects one by one     {slow * 1e6:10.1f} us")
    print(f"  ratio                        {slow / fast:10.0f}x")

    load = scene(links).with_poses(frame(links))
    stream = ros.MarkerStream(load)
    moved = frame(links, seed=1)
    update = seconds_per_call(lambda: stream.update(moved), args.budget)
    rebuild = seconds_per_call(
        lambda: ros.marker_array_cdr(load.with_poses(moved), delete_all=False), args.budget
    )
    print(
        f"\ndraw -> MarkerArray CDR, {len(stream)} markers ({links} links, a fifth of them capsules: 3 markers each)"
    )
    print(f"  MarkerStream.update (template)   {update * 1e3:8.2f} ms")
    print(f"  marker_array_cdr (rebuilt)       {rebuild * 1e3:8.2f} ms   ratio {rebuild / update:.0f}x")

    print(f"\nload -> target, {load.geometry_count()} geometries (goal: each under 20 ms)")
    rows: list[tuple[str, Callable[[], object]]] = [
        ("MarkerArray CDR (marker_array_cdr)", lambda: ros.marker_array_cdr(load)),
        ("  object path: rosbags MarkerArray -> CDR", lambda: ros.to_cdr(ros.marker_array(load))),
        ("ign Model bytes (model().SerializeToString)", lambda: ign.model(load).SerializeToString()),
        ("ign Model_V bytes", lambda: ign.model_v(load).SerializeToString()),
        (
            "tree viewer JSON envelopes (load_requests)",
            lambda: [tv.encode(r) for r in tv.load_requests(load)],
        ),
        ("draw -> ign Pose_V bytes", lambda: ign.pose_v(moved).SerializeToString()),
        ("draw -> tree viewer settransform envelope", lambda: tv.encode(tv.draw_request(moved))),
    ]
    for label, call in rows:
        print(f"  {label:<46} {seconds_per_call(call, args.budget) * 1e3:8.2f} ms")


if __name__ == "__main__":
    main()
