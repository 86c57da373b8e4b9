"""ROS 2 without ROS: the ``darwin ros2`` adapter that makes the robot a native ROS 2 node, on
rmw_zenoh's wire format (:mod:`clients.rmw`)."""
