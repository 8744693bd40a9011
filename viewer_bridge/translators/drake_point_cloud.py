"""Drake's other viewer traffic, as meldis shows it: point clouds (both ways) and frames as triads.

`DRAKE_POINT_CLOUD*` (`lcmt_point_cloud`) -> `sensor_msgs/PointCloud2` or a tree viewer
`pointcloud`; a ROS `PointCloud2` -> `lcmt_point_cloud`, so a ROS camera's cloud shows in
meldis; `DRAKE_DRAW_FRAMES*` (an `lcmt_viewer_draw` whose links are frames) -> a MarkerArray of
triads, drawn as meldis draws them (0.25 m axes, red x, green y, blue z).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from pydantic import Field

from viewer_bridge.formats import ros
from viewer_bridge.formats.drake.point_cloud import cloud_from_lcm, cloud_to_lcm
from viewer_bridge.formats.ros import POINT_CLOUD2
from viewer_bridge.formats.ros.markers import marker_array_cdr
from viewer_bridge.formats.ros.point_cloud import cloud_from_cdr, cloud_to_cdr
from viewer_bridge.formats.tree_viewer import envelope
from viewer_bridge.formats.tree_viewer.requests import geometry_command
from viewer_bridge.model.scene import Geometry, Link, Pose, Scene, StampedPointCloud, Triad
from viewer_bridge.translators.base import Output, Outputs, Translator, TranslatorOptions
from viewer_bridge.translators.drake_stream import DrawReader
from viewer_bridge.translators.options import MarkerOptions, StampOptions
from viewer_bridge.translators.types import DRAW_TYPE, ENVELOPE_TYPE, POINT_CLOUD_TYPE, ros_type
from viewer_bridge.transports.base import Received

MELDIS_TRIAD_LENGTH = 0.25  # meldis's _DrawFrameApplet: 0.25 m axes, 0.01 m radius


def _lcm_cloud(message: Received) -> StampedPointCloud:
    return cloud_from_lcm(message.data)


def lcm_cloud(message: Received) -> StampedPointCloud:
    """A received `lcmt_point_cloud`, decoded once for every route that reads it."""
    return message.decoded(_lcm_cloud)


class PointCloudToRosOptions(StampOptions):
    frame_id: str = "world"  # for a cloud whose frame_name is empty


class DrakePointCloudToRos(Translator):
    """`lcmt_point_cloud` -> `sensor_msgs/PointCloud2` (x, y, z, rgb, normals as Drake sent them).
    Latched, so a late RViz gets the last cloud."""

    Options = PointCloudToRosOptions
    options: PointCloudToRosOptions
    reads = (POINT_CLOUD_TYPE,)
    outputs = (Output("", ros_type(POINT_CLOUD2), latched=True),)

    def translate(self, message: Received) -> Outputs:
        cloud = lcm_cloud(message)  # its utime is sim time; its receive time unless the clock is sim
        if not self.options.sim_stamps(self.shared.clock):
            cloud = replace(cloud, time_us=message.received_us)
        return [(0, cloud_to_cdr(cloud, self.options.frame_id))]


class RosPointCloudToDrake(Translator):
    """`sensor_msgs/PointCloud2` -> `lcmt_point_cloud` laid out as Drake's PointCloudToLcm lays it
    out (what meldis reads); points that are not finite are left out, as Drake leaves them out."""

    reads = (ros_type(POINT_CLOUD2),)
    outputs = (Output("", POINT_CLOUD_TYPE),)

    def translate(self, message: Received) -> Outputs:
        return [(0, cloud_to_lcm(cloud_from_cdr(message.data)))]


class PointCloudToTreeViewerOptions(TranslatorOptions):
    prefix: list[str] = ["point_clouds"]  # the cloud of DRAKE_POINT_CLOUD_FOO goes to <prefix>/FOO


class DrakePointCloudToTreeViewer(Translator):
    """`lcmt_point_cloud` -> a tree viewer `setgeometry` of one `pointcloud` (with its colours),
    at `<prefix>/<channel suffix>` (`default` for DRAKE_POINT_CLOUD), as meldis names them."""

    Options = PointCloudToTreeViewerOptions
    options: PointCloudToTreeViewerOptions
    reads = (POINT_CLOUD_TYPE,)
    outputs = (Output("", ENVELOPE_TYPE),)

    def translate(self, message: Received) -> Outputs:
        stamped = lcm_cloud(message)
        name = message.channel.removeprefix("DRAKE_POINT_CLOUD").lstrip("_") or "default"
        command = geometry_command(stamped.cloud, Pose(), (1.0, 1.0, 1.0, 1.0))
        request = {
            "timestamp": stamped.time_us,
            "setgeometry": [{"path": [*self.options.prefix, name], "geometry": command}],
            "settransform": [],
            "delete": [],
        }
        return [(0, envelope.encode(request))]


class DrawFramesOptions(MarkerOptions):
    length: float = Field(MELDIS_TRIAD_LENGTH, gt=0)  # of each axis, in metres


class DrakeDrawFramesToMarkers(DrawReader):
    """`lcmt_viewer_draw` of frames (DRAKE_DRAW_FRAMES) -> a MarkerArray of triads in the world
    frame, one per frame, every draw; DELETEALL first when the set of frames changes (as meldis
    deletes its old triads). Latched, so a late RViz gets the last frames."""

    Options = DrawFramesOptions
    options: DrawFramesOptions
    reads = (DRAW_TYPE,)
    outputs = (Output("", ros_type(ros.MARKER_ARRAY), latched=True),)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.names: tuple[str, ...] | None = None
        self.triad = (Geometry(Triad(self.options.length, tube=True)),)

    def translate(self, message: Received) -> Outputs:
        poses = self.draw_poses(message)
        links = tuple(
            Link(name, int(robot_num), self.triad)
            for name, robot_num in zip(poses.names, poses.robot_nums, strict=True)
        )
        changed = poses.names != self.names
        self.names = poses.names
        return [
            (0, marker_array_cdr(Scene(links, poses), self.options.table_overrides(), delete_all=changed))
        ]
