"""Helpers for the tests and benchmarks, kept out of the installed packages.

`bag_writer` (ROS1/ROS2 bags with known content), `crowd` (synthetic walkers as ground truth),
`evaluation` (detection and CLEAR-MOT scores, with the dev-only motmetrics), `run_studies` (small
study folders and a scripted controller for `trials run`), `synthetic_study` (finished study
folders for `trials report`), `blinding` (controller names in files and MCAPs), `scripts`
(scripts/*.py loaded as modules); for live runs through real middleware, `ros1_master` (a real rosmaster
on a free port), `ros1_echo` and `ros2_talker` (transport test nodes), `live_rig` (the software robot,
a witness of the velocity commands and `trials run --robot` as processes), `witness`, `press_estop`
and `failing_drive` (the rig's nodes).
"""
