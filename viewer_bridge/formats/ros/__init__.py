"""ROS 2 (Jazzy) messages to and from the scene model, one module per message family.

`messages` builds any message as a rosbags object (no ROS installation needed) and turns it into
CDR or an rclpy object; `cdr` writes and reads CDR directly, for the per-frame fast paths of
`poses` (PoseArray), `markers` (MarkerArray), `tf` (TFMessage), `point_cloud` (PointCloud2) and
`contact` (contact markers and WrenchStamped); `shapes` writes shape_msgs. `tables` binds
`mappings/ros.yaml` (which shape becomes which message or marker) to its encoders.
`message_types` names the message types once, and the world frame.
"""
