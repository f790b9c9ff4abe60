"""Robot logs: ROS1/ROS2 bags and MCAP, lidar person detection and Kalman tracking.

Reading: `reader.LogReader` (one interface over every format) on `sources` (the formats and
layouts), `mcap_chunks` and `inflate` (chunks and files decompressed within a bound), `bag_metadata` (ROS2 bag folders)
and `decoding` (definitions and encodings); `topics`
(choice by type), `convert` (messages to `records`), `summary` (`trials log inspect`). Perception: `detection`, `tracking`, `pipeline`
(`PersonTracker`), `static_world` and `occupancy_map` (ROS map_server maps), `log_tracking` (a whole log), `tracks` (CSV, `history_at`). Simulation:
`lidar_sim`. Writing: `foxglove_log` (MCAP run logs for Foxglove), `track_mcap`. Times are header
stamps throughout (see `reader`). Writing bags, synthetic walkers and scoring against ground truth
are test helpers (tests/support). The bottom layer any package may import: `physical` (shared facts)
and `figure_files` (saving figures as PNG and SVG).
"""
