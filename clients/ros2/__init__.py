"""ROS 2 without ROS: rmw_zenoh's wire format (keys, liveliness tokens, attachments, CDR) and the
``darwin ros2`` adapter that makes the robot a native ROS 2 node."""
