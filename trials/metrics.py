"""The metrics of a run (the measured part of its `outcomes.csv` row), computed from its trace at the physics rate.

The same function scores a run as it finishes and a run read back from its MCAP
(`trials log show`), so the two always agree. Gaps are between the robot's footprint and each
pedestrian's body disc; times count the physics steps at which a condition held.
"""

from __future__ import annotations

import numpy as np

from analysis.records import RunMetrics
from robot_logs.physical import INTIMATE_M, PEDESTRIAN_RADIUS_M, PERSONAL_M
from trials.sim.robot import RobotLimits, footprint_gaps

STILL_SPEED, TURNING_RATE = 0.05, 0.3
#: Standing still during the first second (starting up) does not count as stopping.
STARTUP_S = 1.0


def measure(status: str, time: np.ndarray, pose: np.ndarray, velocity: np.ndarray, pedestrians: np.ndarray,
            limits: RobotLimits = RobotLimits(), pedestrian_radius: float = PEDESTRIAN_RADIUS_M) -> RunMetrics:
    """Score a run.

    Args:
        status: how it ended ("goal", "collision", "timeout").
        time: (K,) sample times (s); pose: (K, 3); velocity: (K, 2) linear and angular.
        pedestrians: (K, N, 2) true pedestrian positions; NaN where a pedestrian is absent (a
            logged person not tracked then).
    """
    time, pose, velocity = np.asarray(time, float), np.asarray(pose, float), np.asarray(velocity, float)
    dt = np.diff(time)
    later = slice(1, None)
    step = np.diff(pose[:, :2], axis=0)
    path = float(np.hypot(step[:, 0], step[:, 1]).sum())
    turned = float(np.abs((np.diff(pose[:, 2]) + np.pi) % (2.0 * np.pi) - np.pi).sum())
    v, w = velocity[:, 0], velocity[:, 1]
    acceleration = np.diff(v) / dt if len(dt) else np.zeros(0)
    jerk = np.diff(acceleration) / dt[1:] if len(dt) > 1 else np.zeros(0)
    n = pedestrians.shape[1] if pedestrians.ndim == 3 else 0
    gaps = (np.array([_nearest(p, q, limits, pedestrian_radius) for p, q in zip(pose, pedestrians)]) if n
            else np.full(len(time), np.inf))
    nearest = gaps[later]
    min_distance = max(float(gaps.min()), 0.0) if np.isfinite(gaps).any() else None
    still = np.abs(v[later]) < STILL_SPEED
    turning = np.abs(w[later]) > TURNING_RATE
    duration = float(time[-1] - time[0])
    return RunMetrics(
        duration_s=duration,
        time_to_goal_s=duration if status == "goal" else None,
        path_length_m=path,
        min_distance_m=min_distance,
        time_within_0_5m_s=float(dt[nearest < INTIMATE_M].sum()),
        time_within_1_2m_s=float(dt[nearest < PERSONAL_M].sum()),
        collisions=int(status == "collision"),
        max_deceleration_mps2=float(max(0.0, -acceleration.min())) if len(acceleration) else 0.0,
        max_jerk_mps3=float(np.abs(jerk).max()) if len(jerk) else 0.0,
        path_irregularity_rad_per_m=turned / path if path > 1e-6 else None,
        turn_in_place_s=float(dt[still & turning].sum()),
        backing_up_s=float(dt[v[later] < -STILL_SPEED].sum()),
        stopped_s=float(dt[still & ~turning & (time[later] > time[0] + STARTUP_S)].sum()),
    )


def _nearest(pose: np.ndarray, people: np.ndarray, limits: RobotLimits, radius: float) -> float:
    """The smallest footprint gap to the pedestrians present (inf with nobody present)."""
    present = people[np.isfinite(people).all(axis=1)]
    return float(footprint_gaps(pose, present, limits, radius).min()) if len(present) else np.inf
