"""Helpers for the tests and benchmarks, kept out of the installed packages.

`bag_writer` (ROS1/ROS2 bags with known content), `crowd` (synthetic walkers as ground truth),
`evaluation` (detection and CLEAR-MOT scores, with the dev-only motmetrics), `run_studies` (small
study folders and a scripted controller for `trials run`), `synthetic_study` (finished study
folders for `trials report`), `blinding` (controller names in files and MCAPs), `scripts`
(scripts/*.py loaded as modules).
"""
