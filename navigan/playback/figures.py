"""Figures of the playback evaluation, drawn once and saved as PNG and SVG by `robot_logs.figure_files`
(matplotlib's object API: no pyplot state).

- the paper's Fig. 4: one episode's full-model path and its intention-only (dagger) path over the
  other agents' footprints, with the observation, the recorded path and the goal;
- the per-step intention and social forces of that episode;
- the distribution of each column's closest approach to others.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from navigan.playback.episodes import GOAL_RADIUS, Episodes
from navigan.playback.metrics import DISCOMFORT_DISTANCE, step_distances
from robot_logs.figure_files import Rendered
from robot_logs.physical import STEP_S

#: Fig. 4 shows the footprints of the agents that come this close (m) to either walked path.
NEAR = 2.0
#: Fig. 4's margin (m) around everything it shows: room for the goal circle and the markers.
MARGIN = 0.75


def plot_paths(episodes: Episodes, e: int, full: np.ndarray, dagger: np.ndarray, forces: np.ndarray,
               title: str) -> Rendered:
    """Fig. 4: the walked paths of episode `e` and each step's social force as an arrow.

    Args:
        full, dagger: (n + 1, 2) the full model's and the dagger variant's paths from time 0.
        forces: (n, 2) the social force on the first way-point at each step of the full path.
    """
    figure = Figure(figsize=(7, 7))
    ax = figure.add_subplot()
    steps = max(len(full), len(dagger))
    others = episodes.others(e)[:steps]
    history = episodes.history()[e]
    recorded = episodes.recorded(e)
    walked = np.full((steps, 2, 2), np.nan)
    walked[: len(full), 0], walked[: len(dagger), 1] = full, dagger
    gap = np.linalg.norm(others[:, :, None] - walked[:, None], axis=-1)  # (steps, others, 2)
    near = np.nanmin(np.where(np.isnan(gap), np.inf, gap), axis=(0, 2)) < NEAR
    # the view: the episode's own extent (its paths, observation, goal and the nearby others while it lasts)
    shown = others[:, near].reshape(-1, 2)
    view = np.concatenate([full, dagger, history, episodes.goal[e][None], shown[np.isfinite(shown).all(axis=1)]])
    low, high = view.min(axis=0) - MARGIN, view.max(axis=0) + MARGIN
    for j in np.flatnonzero(near):
        track = others[:, j]
        ax.plot(track[:, 0], track[:, 1], color="0.7", lw=0.8, marker=".", ms=4, mfc="0.55", mec="none", zorder=1)
    ax.plot([], [], color="0.6", marker=".", lw=0.8, label=f"others within {NEAR:g} m (recorded footprints)")
    ax.plot(recorded[:, 0], recorded[:, 1], color="tab:green", lw=1, ls=":", label="recorded path")
    ax.plot(history[:, 0], history[:, 1], color="black", marker="o", ms=3, lw=1.5, label="observed")
    ax.plot(dagger[:, 0], dagger[:, 1], color="tab:orange", ls="--", marker=".", ms=4, lw=1.5,
            label="intention only (dagger)")
    ax.plot(full[:, 0], full[:, 1], color="tab:blue", marker=".", ms=4, lw=1.8, label="full (intention + social force)")
    n = min(len(forces), len(full) - 1)
    ax.quiver(full[:n, 0], full[:n, 1], forces[:n, 0], forces[:n, 1], color="tab:red", angles="xy",
              scale_units="xy", scale=0.2, width=0.004, zorder=4, label="social force (x5)")
    ax.add_patch(Circle(tuple(episodes.goal[e]), GOAL_RADIUS, fill=False, ls=":", color="tab:red"))
    ax.scatter(*episodes.goal[e], marker="*", s=180, color="tab:red", zorder=5, label="goal")
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3)
    figure.tight_layout()
    return Rendered(figure)


def plot_forces(episodes: Episodes, e: int, path: np.ndarray, plans: np.ndarray, title: str) -> Rendered:
    """Per step of the full path: the intention's and the social force's pull, and the closest approach.

    Args:
        path: (n + 1, 2) the full model's path.
        plans: (n, 3, T_PRED, 2) each step's way-points, intention and forces.
    """
    n = len(path) - 1
    time = np.arange(1, n + 1) * STEP_S
    intention = np.linalg.norm(plans[:n, 1, 0] - path[:n], axis=-1) / STEP_S
    force = np.linalg.norm(plans[:n, 2, 0], axis=-1) / STEP_S
    walked = np.linalg.norm(np.diff(path, axis=0), axis=-1) / STEP_S
    closest = step_distances(path.astype(np.float64), episodes.others(e)[: n + 1].astype(np.float64))
    figure = Figure(figsize=(7, 5))
    top, bottom = figure.subplots(2, 1, sharex=True)
    top.plot(time, intention, color="tab:orange", marker=".", label="intention step / 0.4 s")
    top.plot(time, force, color="tab:red", marker=".", label="social force / 0.4 s")
    top.plot(time, walked, color="tab:blue", lw=1, label="walked speed")
    top.set_ylabel("m/s")
    top.legend(fontsize=7)
    top.set_title(title, fontsize=10)
    bottom.plot(time, np.where(np.isinf(closest), np.nan, closest), color="black", marker=".")
    bottom.axhline(DISCOMFORT_DISTANCE, color="tab:red", ls="--", lw=1, label="0.2 m (comfort)")
    bottom.set_ylabel("closest other (m)")
    bottom.set_xlabel("time since the last observation (s)")
    bottom.legend(fontsize=7)
    figure.tight_layout()
    return Rendered(figure)


def plot_min_distances(closest: Mapping[str, Sequence[float]], title: str) -> Rendered:
    """Box plots of each column's per-episode closest approach (episodes alone are left out)."""
    labels = list(closest)
    data = [[d for d in closest[k] if np.isfinite(d)] or [np.nan] for k in labels]
    figure = Figure(figsize=(8, 4))
    ax = figure.add_subplot()
    ax.boxplot(data, showfliers=True)
    ax.set_xticks(range(1, len(labels) + 1), labels)
    ax.axhline(DISCOMFORT_DISTANCE, color="tab:red", ls="--", lw=1, label="0.2 m")
    highest = max((max(d) for d in data if np.isfinite(d).any()), default=1.0)
    ax.set_ylim(0, min(3.0, highest * 1.05))
    ax.set_ylabel("closest approach over the episode (m, up to 3)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    figure.tight_layout()
    return Rendered(figure)
