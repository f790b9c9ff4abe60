"""Robot logs: ROS1/ROS2 bags and MCAP, lidar person detection and Kalman tracking.

Reading: `reader.LogReader` (one interface over every format), `topics` (choice by type),
`convert` (messages to `records`). Perception: `detection`, `tracking`, `pipeline`
(`PersonTracker`), `log_tracking` (a whole log), `tracks` (CSV, `history_at`). Simulation:
`lidar_sim`. Writing: `foxglove_log` (MCAP run logs for Foxglove), `track_mcap`. Times are header
stamps throughout (see `reader`). Writing bags, synthetic walkers and scoring against ground truth
are test helpers (tests/support).
"""
