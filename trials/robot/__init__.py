"""Live runs on a robot reached through ROS: the `[robot]` table, the middleware links, the live loop
that drives the robot with a run's controller, and the software robot that stands in for one."""
