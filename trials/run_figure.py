"""A picture of one run from above: the robot's path and footprint with time marks, the pedestrians' paths, goal and cone;
drawn from a run's log as `trials log show` and the console's run page show it."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from robot_logs.figure_files import BODY_TEXT_PT, FIGURE_WIDTH_IN, Rendered
from robot_logs.physical import GOAL_TOLERANCE_M, PEDESTRIAN_RADIUS_M
from robot_logs.run_log import LoggedRun
from trials.scenario import CONE, GOAL
from trials.sim.robot import RobotLimits

#: Seconds between the robot outlines drawn along its path.
OUTLINE_EVERY_S = 1.0
#: Seconds between the time marks on every path (the same instants on the robot's and the pedestrians').
MARK_EVERY_S = 2.0
#: A run log's metadata that is not one of its settings: its code, what `trials log show` says apart (seed, perception,
#: the log played, a simulated scene's variation and noise) and the controller, which a blinded run's log never holds.
NOT_SETTINGS = frozenset({"run_code", "study", "seed", "perception", "timeout_s", "variation", "noise_std_m", "dropout", "range_m",
                          "controller", "weights", "log", "log_format", "log_frame", "scan_topic", "odometry", "log_start_stamp",
                          "log_offset_s", "goal_x", "goal_y", "log_damage", "static_map"})
#: The robot is black; the pedestrians take tab10's colours, none of which is black or grey-black.
ROBOT_COLOUR = "black"
PEDESTRIAN_COLOURS = "tab10"


def _outline(pose: np.ndarray, limits: RobotLimits) -> np.ndarray:
    corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1], [1, 1]]) * (limits.half_length, limits.half_width)
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return corners @ np.array([[c, s], [-s, c]]) + pose[:2]


def mark_indices(time: np.ndarray, every_s: float = MARK_EVERY_S) -> np.ndarray:
    """The samples nearest 0, every_s, 2 every_s, ... seconds of the run's clock (`time` sorted)."""
    if not len(time):
        return np.zeros(0, dtype=int)
    marks = np.arange(time[0], time[-1] + 1e-9, every_s)
    return np.unique(np.abs(time[None, :] - marks[:, None]).argmin(axis=1))


def run_figure(run: LoggedRun, title: str, goal: tuple[float, float], cone: tuple[float, float] | None,
               limits: RobotLimits = RobotLimits()) -> Rendered:
    """The run's trajectories (a logged trial has no cone, and its people come and go), a report column wide with its
    text at the body text's size, the legend against the axes' right side so it never hides a path."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    figure = Figure(figsize=(FIGURE_WIDTH_IN, 4.8), layout="constrained")
    axes = figure.add_subplot()
    step = max(int(round(OUTLINE_EVERY_S / max(np.median(np.diff(run.time)), 1e-3))), 1) if len(run.time) > 1 else 1
    for k in range(0, len(run.time), step):
        outline = _outline(run.pose[k], limits)
        axes.plot(outline[:, 0], outline[:, 1], color=ROBOT_COLOUR, linewidth=0.5, alpha=0.35)
    axes.plot(run.pose[:, 0], run.pose[:, 1], color=ROBOT_COLOUR, linewidth=2.0, label="robot", zorder=3)
    marks = mark_indices(run.time)
    axes.plot(run.pose[marks, 0], run.pose[marks, 1], "o", color=ROBOT_COLOUR, markersize=4, zorder=4)
    for k in marks[1:]:
        axes.annotate(f"{run.time[k] - run.time[0]:.0f}", tuple(run.pose[k, :2]), textcoords="offset points", xytext=(3, -11),
                      fontsize=BODY_TEXT_PT, color=ROBOT_COLOUR)
    colours = colormaps[PEDESTRIAN_COLOURS]
    for j, pid in enumerate(run.ids):
        colour = colours(j % colours.N)
        path = run.pedestrians[:, j, :]
        axes.plot(path[:, 0], path[:, 1], color=colour, linewidth=1.2, label=f"pedestrian {pid}")
        seen = np.isfinite(path).all(axis=1)
        marked = marks[seen[marks]]
        axes.plot(path[marked, 0], path[marked, 1], "o", color=colour, markersize=3)
        path = path[seen]
        axes.plot(*path[0], marker="^", color=colour, markersize=5)
        axes.add_patch(Circle(tuple(path[-1]), PEDESTRIAN_RADIUS_M, color=colour, alpha=0.5))
        axes.annotate(str(pid), tuple(path[0]), textcoords="offset points", xytext=(4, 4), fontsize=BODY_TEXT_PT)
    axes.add_patch(Circle(goal, GOAL_TOLERANCE_M, color="green", alpha=0.25, label=f"goal ({GOAL_TOLERANCE_M:g} m)"))
    if cone is not None:
        axes.plot(*cone, marker="^", color="orangered", markersize=9, linestyle="none", label="cone")
    for t, name, _detail in run.events:
        if name == "collision":
            k = int(np.searchsorted(run.time, t))
            axes.plot(*run.pose[min(k, len(run.pose) - 1), :2], marker="x", color="red", markersize=12, mew=3, label="collision")
    axes.plot([], [], "o", color="0.3", markersize=4, label=f"every {MARK_EVERY_S:g} s (robot: s)")
    axes.plot([], [], "^", color="0.3", markersize=5, linestyle="none", label="pedestrian's start")
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)", fontsize=BODY_TEXT_PT)
    axes.set_ylabel("y (m)", fontsize=BODY_TEXT_PT)
    axes.tick_params(labelsize=BODY_TEXT_PT)
    axes.set_title(title, fontsize=BODY_TEXT_PT, wrap=True)
    axes.grid(alpha=0.3)
    axes.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=BODY_TEXT_PT)
    return Rendered(figure)


def run_settings(metadata: Mapping[str, str]) -> str:
    """A run's settings from its log's metadata, "Pedestrians 2, Controller A" (a blinded factor by its arm label)."""
    return ", ".join(f"{k} {v}" for k, v in metadata.items() if k not in NOT_SETTINGS)


def log_figure(run: LoggedRun, code: str) -> Rendered:
    """The picture of a run's log, titled with its code, settings and ending: a simulated run's goal and cone, a logged
    trial's goal from its metadata (and no cone)."""
    meta = run.metadata
    logged = "log" in meta
    goal = (float(meta["goal_x"]), float(meta["goal_y"])) if logged else GOAL
    return run_figure(run, f"run {code}: {run_settings(meta)}; {run.status or 'unfinished'}", goal, None if logged else CONE)
