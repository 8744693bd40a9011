"""`TRANSLATORS`: the registry a route's `translator:` word is looked up in, by name.

The built-in translators are named here and imported when first looked up; a plugin adds one with
an entry point in the group `viewer_bridge.translators` naming a `Translator` subclass.
"""

from __future__ import annotations

from viewer_bridge.translators.base import Translator
from viewer_bridge.util.registry import Registry

_BUILTINS = {
    "drake_to_marker_array": "drake_ros:DrakeToMarkerArray",
    "drake_to_pose_array": "drake_ros:DrakeToPoseArray",
    "drake_to_shapes": "drake_ros:DrakeToShapes",
    "drake_to_clock": "drake_ros:DrakeToClock",
    "drake_link_to_marker_array": "drake_ros:DrakeLinkToMarkerArray",
    "ros_pose_array_to_drake_draw": "drake_ros:RosPoseArrayToDrakeDraw",
    "lcm_bytes_to_ros": "drake_ros:LcmBytesToRos",
    "lcm_relay": "relay:LcmRelay",
    "lcm_to_ros": "lcm_generic:LcmToRos",
    "ros_to_lcm": "lcm_generic:RosToLcm",
    "ros_topic_to_lcm": "ros_topics:RosTopicToLcm",
    "drake_to_tf": "drake_tf:DrakeToTf",
    "drake_to_link_markers": "drake_tf:DrakeToLinkMarkers",
    "drake_to_scene_update": "drake_foxglove:DrakeToSceneUpdate",
    "drake_to_frame_transforms": "drake_foxglove:DrakeToFrameTransforms",
    "tree_viewer_server": "tree_viewer:TreeViewerServer",
    "drake_to_tree_viewer": "tree_viewer:DrakeToTreeViewer",
    "drake_to_ign_model": "drake_ign:DrakeToIgnModel",
    "drake_to_ign_model_v": "drake_ign:DrakeToIgnModelV",
    "drake_to_ign_pose_v": "drake_ign:DrakeToIgnPoseV",
    "drake_to_ign_poses_stamped": "drake_ign:DrakeToIgnPosesStamped",
    "ign_pose_v_to_drake_draw": "drake_ign:IgnPoseVToDrakeDraw",
    "drake_point_cloud_to_ros": "drake_point_cloud:DrakePointCloudToRos",
    "ros_point_cloud_to_drake": "drake_point_cloud:RosPointCloudToDrake",
    "drake_point_cloud_to_tree_viewer": "drake_point_cloud:DrakePointCloudToTreeViewer",
    "drake_draw_frames_to_markers": "drake_point_cloud:DrakeDrawFramesToMarkers",
    "drake_contacts_to_marker_array": "drake_contact:DrakeContactsToMarkerArray",
    "drake_contacts_to_wrenches": "drake_contact:DrakeContactsToWrenches",
    "drake_contacts_to_ign_contacts": "drake_contact:DrakeContactsToIgnContacts",
    "drake_contacts_to_tree_viewer": "drake_contact:DrakeContactsToTreeViewer",
    "drake_images_to_ros": "drake_image:DrakeImagesToRos",
    "drake_images_to_foxglove": "drake_image:DrakeImagesToFoxglove",
    "ros_image_to_drake": "drake_image:RosImageToDrake",
    "drake_to_rerun": "drake_rerun:DrakeToRerun",
    "drake_images_to_rerun": "drake_rerun:DrakeImagesToRerun",
    "drake_point_cloud_to_rerun": "drake_rerun:DrakePointCloudToRerun",
    "drake_draw_frames_to_rerun": "drake_rerun:DrakeDrawFramesToRerun",
    "drake_contacts_to_rerun": "drake_rerun:DrakeContactsToRerun",
    "lcm_to_rerun_scalars": "lcm_rerun:LcmToRerunScalars",
}

TRANSLATORS: Registry[Translator] = Registry(
    "translator",
    "viewer_bridge.translators",
    {name: f"viewer_bridge.translators.{target}" for name, target in _BUILTINS.items()},
    Translator,
)
