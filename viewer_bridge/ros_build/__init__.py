"""ROS 2 interface packages for types PyPI has no wheel for: written, built and installed into the
venv (`interfaces`), or built in the background while the bridge runs (`background`)."""
