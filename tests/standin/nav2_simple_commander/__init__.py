"""A stand-in for Nav2's ``nav2_simple_commander`` (see ``robot_navigator``)."""
