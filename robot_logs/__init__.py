"""Robot logs: ROS1/ROS2 bags and MCAP, lidar person detection and Kalman tracking."""
