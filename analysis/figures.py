"""Figures shared by `trials design` and `trials report`, drawn off-screen with matplotlib's object API and
saved through `robot_logs.figure_files`."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from robot_logs.figure_files import Rendered, quiet_glyphs

#: Panels a row in the report's trajectory figure.
TRAJECTORY_COLUMNS = 4


def correlation_map_figure(columns: list[str], correlations: np.ndarray, title: str) -> Rendered:
    """JMP's colour map on correlations, signed: r between model columns, blue -1 through white 0 to red +1."""
    size = 2.5 + 0.45 * len(columns)
    figure = Figure(figsize=(size + 1.5, size))
    axes = figure.add_subplot()
    image = axes.imshow(correlations, cmap="RdBu_r", vmin=-1.0, vmax=1.0)
    axes.set_xticks(range(len(columns)), columns, rotation=60, ha="right", fontsize=8)
    axes.set_yticks(range(len(columns)), columns, fontsize=8)
    for (i, j), value in np.ndenumerate(correlations):
        if not np.isnan(value):
            axes.text(j, i, f"{value:.2f}", ha="center", va="center", fontsize=6, color="white" if abs(value) > 0.6 else "black")
    figure.colorbar(image, ax=axes, label="correlation")
    axes.set_title(title)
    with quiet_glyphs():
        figure.tight_layout()
    return _rendered(figure)


def design_evaluation_figure(fraction: tuple[np.ndarray, np.ndarray], profiles: list[tuple[str, list[float], list[float], list[str]]],
                             title: str) -> Rendered:
    """JMP's design evaluation views: the fraction of design space plot (left) and the prediction variance
    profile, one panel per factor (right); variances relative to sigma^2, on one scale."""
    width = 4.0 + 2.2 * len(profiles)
    figure = Figure(figsize=(width, 3.6))
    grid = figure.add_gridspec(1, len(profiles) + 2)
    fds = figure.add_subplot(grid[0, :2])
    fds.plot(fraction[0], fraction[1], color="#1f77b4")
    fds.set_xlabel("fraction of design space")
    fds.set_ylabel("relative prediction variance")
    fds.set_xlim(0.0, 1.0)
    fds.set_title("Fraction of design space", fontsize=9)
    top = 1.05 * max(float(np.max(fraction[1])), *(max(v) for _, _, v, _ in profiles))
    fds.set_ylim(0.0, top)
    for k, (name, x, variance, labels) in enumerate(profiles):
        axes = figure.add_subplot(grid[0, k + 2], sharey=fds)
        if labels:
            axes.plot(range(len(labels)), variance, "o-", color="#d62728")
            axes.set_xticks(range(len(labels)), labels, rotation=45, ha="right", fontsize=7)
        else:
            axes.plot(x, variance, color="#d62728")
        axes.set_xlabel(name, fontsize=8)
        axes.tick_params(labelleft=False)
    figure.suptitle(title, fontsize=10)
    figure.subplots_adjust(left=0.8 / width, right=1 - 0.15 / width, bottom=0.3, top=0.85, wspace=0.15)  # fixed: tight_layout costs more than the drawing
    return _rendered(figure)


def _rendered(figure: Figure) -> Rendered:
    return Rendered(figure)


def arm_colours(arms: list[str]) -> dict[str, str]:
    """One colour per arm, the same in every figure of a report."""
    palette = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"]
    return {arm: palette[i % len(palette)] for i, arm in enumerate(arms)}


def score_distribution_figure(groups: dict[str, list[int]], paper: dict[int, float] | None, title: str) -> Rendered:
    """Share of runs scored 1, 2, 3 for each group (counts [n1, n2, n3]) with Wilson 95 % intervals, and the
    paper's shares as markers."""
    from analysis.intervals import wilson  # here: statsmodels and scipy.stats cost `trials design` a second to import
    figure = Figure(figsize=(6.5, 3.6))
    axes = figure.add_subplot()
    width = 0.8 / max(len(groups), 1)
    colours = arm_colours(list(groups))
    for i, (group, counts) in enumerate(groups.items()):
        total = sum(counts)
        x = np.arange(3) + (i - (len(groups) - 1) / 2) * width
        shares = [wilson(c, total) if total else None for c in counts]
        heights = [100.0 * s.share if s else 0.0 for s in shares]
        # an interval always holds its share; clip rounding so matplotlib never sees a negative bar
        errors = np.clip([[100.0 * (s.share - s.low) if s else 0.0 for s in shares],
                          [100.0 * (s.high - s.share) if s else 0.0 for s in shares]], 0.0, None)
        axes.bar(x, heights, width, color=colours[group], yerr=errors, capsize=3, ecolor="0.25", label=f"{group} (n = {total})")
        for where, count in zip(x, counts):  # counts under the bars, clear of the intervals
            axes.text(where, -1.5, str(count), ha="center", va="top", fontsize=8, color=colours[group])
    if paper is not None:
        axes.scatter(range(3), [paper[s] for s in (1, 2, 3)], marker="D", color="black", zorder=3, label="paper")
    axes.set_xticks(range(3), ["1: collision", "2: unnatural", "3: natural"])
    axes.tick_params(axis="x", pad=14)
    axes.set_ylabel("% of runs (Wilson 95 % interval)")
    axes.set_ylim(0, 105)
    axes.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    axes.set_title(title)
    figure.tight_layout()
    return _rendered(figure)


def trajectories_figure(panels: list[tuple[str, str, np.ndarray, list[np.ndarray]]], colours: dict[str, str], arm_word: str) -> Rendered:
    """Small multiples, one panel per run: (title, arm, robot path (n, 2), pedestrian paths [(m, 2)]); robots coloured by arm.

    Four panels a row at a size where tick labels and titles read at 8 pt; the panels share their axes, so
    only the outer ones carry tick labels."""
    columns = min(TRAJECTORY_COLUMNS, max(len(panels), 1))
    rows = max(1, -(-len(panels) // columns))
    every = [p for _, _, robot, peds in panels for p in [robot, *peds] if len(p)]
    points = np.vstack(every) if every else np.zeros((1, 2))
    low, high = points.min(axis=0) - 0.5, points.max(axis=0) + 0.5
    aspect = float(np.clip((high[1] - low[1]) / (high[0] - low[0]), 0.3, 1.5))
    panel = 2.6
    figure = Figure(figsize=(panel * columns + 0.6, rows * (panel * aspect + 0.45) + 0.9), layout="constrained")
    grid = figure.subplots(rows, columns, sharex=True, sharey=True, squeeze=False)
    for index, axes in enumerate(grid.flat):
        if index >= len(panels):
            axes.set_visible(False)
            continue
        title, arm, robot, pedestrians = panels[index]
        for path in pedestrians:
            axes.plot(path[:, 0], path[:, 1], color="0.6", linewidth=0.8)
            axes.plot(path[-1:, 0], path[-1:, 1], "o", color="0.45", markersize=2.5)
        axes.plot(robot[:, 0], robot[:, 1], color=colours.get(arm, "black"), linewidth=1.6)
        axes.plot(robot[-1:, 0], robot[-1:, 1], "s", color=colours.get(arm, "black"), markersize=3.5)
        axes.set_xlim(low[0], high[0])
        axes.set_ylim(low[1], high[1])
        axes.set_aspect("equal")
        axes.set_title(title, fontsize=8, wrap=True)
        axes.tick_params(labelsize=8)
    figure.suptitle(f"Robot (colour: {arm_word}) and pedestrian (grey) paths, m; markers at the end", fontsize=10)
    handles = [Line2D([], [], color=colour, linewidth=1.6, label=arm) for arm, colour in colours.items()]
    handles.append(Line2D([], [], color="0.6", linewidth=0.8, label="pedestrian"))
    figure.legend(handles=handles, loc="outside lower center", fontsize=8, ncol=len(handles), frameon=False)
    return _rendered(figure)


def shares_figure(rows: list[tuple[int, dict[str, tuple[float, float, float]]]], paper: dict[str, dict[int, float]] | None, title: str) -> Rendered:
    """Share judged compliant (with its interval) per arm for runs with >= k pedestrians: rows of (k, arm -> (share, low, high))."""
    arms = list(rows[0][1]) if rows else []
    colours = arm_colours(arms)
    figure = Figure(figsize=(6.5, 3.6))
    axes = figure.add_subplot()
    width = 0.8 / max(len(arms), 1)
    for i, arm in enumerate(arms):
        x = np.arange(len(rows)) + (i - (len(arms) - 1) / 2) * width
        share = np.array([100.0 * r[1][arm][0] for r in rows])
        low = np.array([100.0 * r[1][arm][1] for r in rows])
        high = np.array([100.0 * r[1][arm][2] for r in rows])
        # matplotlib refuses negative error bars; an interval always holds its share, so clip rounding
        yerr = np.clip([share - low, high - share], 0.0, None)
        axes.errorbar(x, share, yerr=yerr, fmt="o", color=colours[arm], capsize=4, label=f"{arm} (Wilson 95 %)")
        if paper is not None and arm in paper:
            axes.scatter(x, [paper[arm].get(k, np.nan) for k, _ in rows], marker="D", facecolors="none", edgecolors=colours[arm], label=f"{arm}: paper")
    axes.set_xticks(range(len(rows)), [f">= {k} pedestrians" for k, _ in rows])
    axes.set_ylabel("% judged socially compliant")
    axes.set_ylim(0, 105)
    axes.legend(fontsize=7, loc="lower left")
    axes.set_title(title)
    figure.tight_layout()
    return _rendered(figure)


def min_distance_figure(points: list[tuple[str, float, float]], arms: list[str], title: str, intimate_m: float) -> Rendered:
    """Minimum gap of each run against its pedestrian count, one colour per arm: points (arm, pedestrians, gap).

    The counts are categories (the design's levels), evenly spaced whatever their values, each arm's runs
    side by side within a category."""
    colours = arm_colours(arms)
    figure = Figure(figsize=(6.5, 3.6))
    axes = figure.add_subplot()
    levels = sorted({int(p) for _, p, _ in points})
    where = {level: i for i, level in enumerate(levels)}
    offsets = np.linspace(-0.2, 0.2, len(arms)) if len(arms) > 1 else [0.0]
    for offset, arm in zip(offsets, arms):
        mine = [(where[int(p)], d) for a, p, d in points if a == arm]
        if not mine:
            continue
        slots, gaps = np.array(mine).T
        axes.plot(slots + offset, gaps, "o", color=colours[arm], alpha=0.8, label=arm)
        present = sorted(set(slots))
        axes.plot(np.array(present) + offset, [gaps[slots == slot].mean() for slot in present], "-", color=colours[arm], linewidth=1)
    axes.axhline(intimate_m, color="0.5", linestyle=":", linewidth=1)
    axes.text(-0.45, intimate_m, f" intimate distance {intimate_m:g} m", fontsize=7, va="bottom", color="0.4")
    axes.set_xticks(range(len(levels)), [str(level) for level in levels])
    axes.set_xlim(-0.5, len(levels) - 0.5)
    axes.set_xlabel("pedestrians")
    axes.set_ylabel("minimum gap to a pedestrian (m)")
    axes.set_ylim(bottom=0)
    axes.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    axes.set_title(title)
    figure.tight_layout()
    return _rendered(figure)


def residuals_figure(panels: list[tuple[str, tuple[float, ...], tuple[float, ...], tuple[bool, ...]]]) -> Rendered:
    """Residual against fitted value, one panel per fit: (title, fitted, residuals, flagged); flagged runs
    (censored values) drawn as open red triangles."""
    figure = Figure(figsize=(3.2 * max(len(panels), 1), 3.2))
    for index, (title, fitted, residuals, flagged) in enumerate(panels):
        axes = figure.add_subplot(1, max(len(panels), 1), index + 1)
        x, y, marked = np.asarray(fitted), np.asarray(residuals), np.asarray(flagged, dtype=bool)
        axes.plot(x[~marked], y[~marked], "o", color="#1f77b4", markersize=4)
        if marked.any():
            axes.plot(x[marked], y[marked], "^", markerfacecolor="none", markeredgecolor="#d62728", markersize=6, label="censored (timeout)")
            axes.legend(fontsize=6)
        axes.axhline(0.0, color="0.5", linewidth=0.8)
        axes.set_title(title, fontsize=8)
        axes.set_xlabel("fitted", fontsize=7)
        axes.set_ylabel("residual", fontsize=7)
        axes.tick_params(labelsize=6)
    figure.tight_layout()
    return _rendered(figure)
