"""A picture of one row's scene as the operator stages it (`trials.robot.staging.StagedScene`): the robot's footprint at
its start with its heading, its goal, and each walker's start, goal and direction, numbered as the staging lines number
them, in the lab's frame; drawn for the run page and the printable staging sheet."""

from __future__ import annotations

import numpy as np

from robot_logs.figure_files import FIGURE_WIDTH_IN, Rendered
from trials.robot.staging import StagedScene
from trials.run_figure import PEDESTRIAN_COLOURS, ROBOT_COLOUR, _outline
from trials.sim.robot import RobotLimits


def staging_figure(scene: StagedScene, limits: RobotLimits = RobotLimits()) -> Rendered:
    """The row's scene from above, a report column wide."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    s = scene.scenario.settings
    figure = Figure(figsize=(FIGURE_WIDTH_IN, 3.6), layout="constrained")
    axes = figure.add_subplot()
    start = np.array([scene.start.x, scene.start.y, scene.start.yaw])
    outline = _outline(start, limits)
    axes.fill(outline[:, 0], outline[:, 1], color=ROBOT_COLOUR, alpha=0.25)
    axes.plot(outline[:, 0], outline[:, 1], color=ROBOT_COLOUR, linewidth=1.0)
    ahead = start[:2] + 1.2 * np.array([np.cos(start[2]), np.sin(start[2])])
    axes.annotate("", ahead, start[:2], arrowprops={"arrowstyle": "-|>", "color": ROBOT_COLOUR, "linewidth": 1.5})
    axes.plot([start[0], scene.goal[0]], [start[1], scene.goal[1]], color=ROBOT_COLOUR, linewidth=0.8, linestyle=":")
    axes.plot(*scene.goal, marker="*", markersize=12, color=ROBOT_COLOUR, linestyle="none", label="robot: start and goal")
    colours = colormaps[PEDESTRIAN_COLOURS]
    axes.plot([], [], marker="o", color="grey", linestyle="none", label="walker: start, and\nwhere it goes")
    for walker in scene.scenario.walkers:
        begin, end = scene.place(np.array([walker.start, walker.goal]))
        colour = colours(walker.id % 10)
        axes.plot(*begin, marker="o", markersize=7, color=colour, linestyle="none")
        axes.annotate("", end, begin, arrowprops={"arrowstyle": "-|>", "color": colour, "linewidth": 1.0, "linestyle": "--"})
        axes.annotate(str(walker.id + 1), begin, textcoords="offset points", xytext=(5, 5), color=colour)
    axes.set_aspect("equal", adjustable="datalim")
    axes.set_xlabel(f"x (m, {scene.frame})")
    axes.set_ylabel(f"y (m, {scene.frame})")
    axes.grid(True, linewidth=0.3)
    axes.set_title(f"Run {scene.code}: {s.direction}, {s.pedestrians} pedestrian{'s' * (s.pedestrians != 1)}"
                   + (f", crossing {s.crossing_distance:g} m ahead" if s.direction != "Parallel" else ""))
    axes.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), frameon=False)
    return Rendered(figure)
