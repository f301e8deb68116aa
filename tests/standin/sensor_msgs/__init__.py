"""``sensor_msgs`` of the stand-in ROS 2 (see ``rclpy``'s docstring)."""
