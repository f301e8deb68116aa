"""A live robot on ROS 2 (an RGB-D camera, tf and Nav2), imported lazily: see ``env``."""
