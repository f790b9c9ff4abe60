"""A picture of one run from above: the robot's path and footprint, the pedestrians' paths, goal and cone."""

from __future__ import annotations

import io

import numpy as np

from robot_logs.physical import GOAL_TOLERANCE_M, PEDESTRIAN_RADIUS_M
from robot_logs.run_log import LoggedRun
from trials.sim.robot import RobotLimits

#: Seconds between the robot outlines drawn along its path.
OUTLINE_EVERY_S = 1.0


def _outline(pose: np.ndarray, limits: RobotLimits) -> np.ndarray:
    corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1], [1, 1]]) * (limits.half_length, limits.half_width)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return corners @ np.array([[c, s], [-s, c]]) + pose[:2]


def run_png(run: LoggedRun, title: str, goal: tuple[float, float], cone: tuple[float, float] | None,
            limits: RobotLimits = RobotLimits()) -> bytes:
    """The run's trajectories as PNG bytes (a logged trial has no cone, and its people come and go)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    figure, axes = plt.subplots(figsize=(8, 6), dpi=110)
    step = max(int(round(OUTLINE_EVERY_S / max(np.median(np.diff(run.time)), 1e-3))), 1) if len(run.time) > 1 else 1
    for k in range(0, len(run.time), step):
        outline = _outline(run.pose[k], limits)
        axes.plot(outline[:, 0], outline[:, 1], color="goldenrod", linewidth=0.6, alpha=0.6)
    axes.plot(run.pose[:, 0], run.pose[:, 1], color="darkorange", linewidth=2.0, label="robot")
    colours = plt.get_cmap("tab10")
    for j, pid in enumerate(run.ids):
        path = run.pedestrians[:, j, :]
        axes.plot(path[:, 0], path[:, 1], color=colours(j % 10), linewidth=1.2)
        path = path[np.isfinite(path).all(axis=1)]
        axes.plot(*path[0], marker="o", color=colours(j % 10), markersize=4)
        axes.add_patch(plt.Circle(tuple(path[-1]), PEDESTRIAN_RADIUS_M, color=colours(j % 10), alpha=0.5))
        axes.annotate(str(pid), tuple(path[0]), textcoords="offset points", xytext=(4, 4), fontsize=8)
    axes.add_patch(plt.Circle(goal, GOAL_TOLERANCE_M, color="green", alpha=0.25, label=f"goal ({GOAL_TOLERANCE_M:g} m)"))
    if cone is not None:
        axes.plot(*cone, marker="^", color="orangered", markersize=9, linestyle="none", label="cone")
    for t, name, _detail in run.events:
        if name == "collision":
            k = int(np.searchsorted(run.time, t))
            axes.plot(*run.pose[min(k, len(run.pose) - 1), :2], marker="x", color="red", markersize=12, mew=3, label="collision")
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(title, fontsize=10)
    axes.grid(alpha=0.3)
    axes.legend(loc="lower left", fontsize=8)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", bbox_inches="tight")
    plt.close(figure)
    return buffer.getvalue()
