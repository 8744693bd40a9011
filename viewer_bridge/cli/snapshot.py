"""`viewer-bridge snapshot`: the current scene of a log or a live LCM bus, rendered to a PNG or JPEG."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from viewer_bridge.cli.arguments import (
    IMAGE_SUFFIXES,
    AddCommand,
    camera,
    field_of_view,
    image_size,
    lcm_source,
    output_file,
    positive,
    regex,
)
from viewer_bridge.errors import SceneError, UsageError
from viewer_bridge.model.skipped import collecting
from viewer_bridge.util.words import counted


def add_command(add: AddCommand) -> None:
    """The `snapshot` command's arguments, on the parser `add` makes."""
    shot = add("snapshot", help="render the current scene of a log or a live LCM bus to a PNG or JPEG")
    shot.add_argument("source", type=lcm_source, help="an .lcmlog file, or an LCM URL to listen on")
    shot.add_argument(
        "out", type=output_file(IMAGE_SUFFIXES), help="the image to write: .png, or .jpg/.jpeg for JPEG"
    )
    shot.add_argument("--role", default="", help="channel suffix, e.g. ILLUSTRATION (default: unsuffixed)")
    shot.add_argument("--image", choices=["color", "label", "depth"], default="color")
    shot.add_argument("--size", type=image_size, default="640x480", help="WIDTHxHEIGHT")
    shot.add_argument("--fov", type=field_of_view, default=45.0, help="vertical field of view, degrees")
    shot.add_argument(
        "--camera",
        type=camera,
        metavar="EX,EY,EZ,TX,TY,TZ",
        help="eye and target (default: frame the scene)",
    )
    shot.add_argument("--duration", type=positive, default=3.0, help="with an LCM URL: seconds to listen")
    shot.add_argument("--contacts", action="store_true", help="draw the last CONTACT_RESULTS over the scene")
    shot.add_argument(
        "--hide",
        type=regex,
        metavar="REGEX",
        help="leave out links whose names match (e.g. a body over a contact)",
    )


def run(args: argparse.Namespace) -> int:
    """Render and write the image; each geometry that cannot be drawn is one warning line."""
    from viewer_bridge.render.snapshot import (  # OpenGL only for this command
        events_from,
        latest_contacts,
        latest_scene,
        snapshot,
        with_contacts,
        without_links,
    )

    width, height = args.size
    eye = target = None
    if args.camera:
        eye, target = np.array(args.camera[:3]), np.array(args.camera[3:])
    jpeg = Path(args.out).suffix.lower() != ".png"
    if jpeg and args.image == "depth":
        raise UsageError("a depth image is 16-bit: write it as .png (JPEG holds 8 bits)")
    events = events_from(args.source, args.duration)
    scene = latest_scene(events, args.role.upper())
    if args.hide:
        scene = without_links(scene, args.hide)
    if args.contacts:
        results = latest_contacts(events)
        if results is None:
            raise SceneError(
                "no CONTACT_RESULTS message in the source: Drake publishes them when a simulation calls "
                "ConnectContactResultsToDrakeVisualizer (`viewer-bridge example contacts` does)"
            )
        scene = with_contacts(scene, results)
    with collecting() as skipped:  # a geometry that cannot be drawn is left out, and named
        picture = snapshot(scene, width, height, args.fov, eye, target, args.image, "JPEG" if jpeg else "PNG")
    for geometry in skipped:
        print(f"viewer-bridge snapshot: warning: {geometry}", file=sys.stderr)
    Path(args.out).write_bytes(picture)
    drawn = scene.geometry_count() - len(skipped)
    print(
        f"wrote {args.out}: {counted(len(scene.links), 'link')}, {counted(drawn, 'geometry', 'geometries')} "
        f"({len(skipped)} skipped)"
    )
    return 0
