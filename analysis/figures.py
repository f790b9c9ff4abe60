"""Figures shared by `trials design` and `trials report`, drawn off-screen with matplotlib's object API and
saved through `robot_logs.figure_files`."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from robot_logs.figure_files import BODY_TEXT_PT, FIGURE_WIDTH_IN, Rendered, quiet_glyphs

#: Every figure is drawn at most a printed report column wide, its smallest text at the body text's size, so no
#: label prints smaller than the text around it (`Rendered.printed_font_pt`).
WIDTH_IN = FIGURE_WIDTH_IN
TEXT_PT = BODY_TEXT_PT
#: Titles, a little larger than the labels.
TITLE_PT = TEXT_PT + 1
#: Panels a row in the report's trajectory figure, and in the design evaluation's variance profile.
TRAJECTORY_COLUMNS = 4
PROFILE_COLUMNS = 3
#: The narrowest cell of the correlation map that holds its value ("-.08") at TEXT_PT, inches; narrower cells
#: show colour only (the values are in design.json).
CELL_FOR_NUMBERS_IN = 0.34


def _r(value: float) -> str:
    """A correlation in four characters at most: 1, .50, -.08."""
    return "1" if value >= 0.995 else "-1" if value <= -0.995 else f"{value:.2f}".replace("0.", ".", 1)


def correlation_map_figure(columns: list[str], correlations: np.ndarray, title: str) -> Rendered:
    """JMP's colour map on correlations, signed: r between model columns, blue -1 through white 0 to red +1, each
    cell's r written in it when the cell is wide enough to read. A column's name breaks at each `*` on the rows."""
    figure = Figure(figsize=(WIDTH_IN, 0.36 * len(columns) + 4.0), layout="constrained")
    axes = figure.add_subplot()
    image = axes.imshow(correlations, cmap="RdBu_r", vmin=-1.0, vmax=1.0)
    axes.set_xticks(range(len(columns)), columns, rotation=90, fontsize=TEXT_PT)
    axes.set_yticks(range(len(columns)), [c.replace("*", "*\n") for c in columns], fontsize=TEXT_PT)
    bar = figure.colorbar(image, ax=axes, location="top", shrink=0.6, aspect=30)
    bar.set_label("r (signed correlation)", fontsize=TEXT_PT)
    bar.ax.tick_params(labelsize=TEXT_PT)
    figure.suptitle(title, fontsize=TITLE_PT, wrap=True)
    with quiet_glyphs():
        figure.draw_without_rendering()
    cell_in = axes.get_window_extent().width / figure.dpi / max(len(columns), 1)
    if cell_in >= CELL_FOR_NUMBERS_IN:
        for (i, j), value in np.ndenumerate(correlations):
            if not np.isnan(value):
                axes.text(j, i, _r(value), ha="center", va="center", fontsize=TEXT_PT, color="white" if abs(value) > 0.6 else "black")
    return _rendered(figure)


def design_evaluation_figure(fraction: tuple[np.ndarray, np.ndarray], profiles: list[tuple[str, list[float], list[float], list[str]]],
                             title: str) -> Rendered:
    """JMP's design evaluation views: the fraction of design space plot (top) and the prediction variance
    profile, one panel per factor, PROFILE_COLUMNS a row (below); variances relative to sigma^2, on one scale."""
    columns = min(max(len(profiles), 1), PROFILE_COLUMNS)
    rows = max(1, -(-len(profiles) // columns))
    figure = Figure(figsize=(WIDTH_IN, 3.0 + 2.8 * rows), layout="constrained")
    top_row, bottom_row = figure.subfigures(2, 1, height_ratios=[3.0, 2.8 * rows])
    fds = top_row.add_subplot()
    fds.plot(fraction[0], fraction[1], color="#1f77b4")
    fds.set_xlabel("fraction of design space", fontsize=TEXT_PT)
    fds.set_ylabel("relative prediction\nvariance", fontsize=TEXT_PT)
    fds.set_xlim(0.0, 1.0)
    fds.set_title("Fraction of design space", fontsize=TEXT_PT)
    fds.tick_params(labelsize=TEXT_PT)
    top = 1.05 * max(float(np.max(fraction[1])), *(max(v) for _, _, v, _ in profiles))
    fds.set_ylim(0.0, top)
    panels = bottom_row.subplots(rows, columns, sharey=True, squeeze=False).flat
    bottom_row.suptitle("Prediction variance profile", fontsize=TEXT_PT)
    for axes in panels[len(profiles):]:
        axes.set_visible(False)
    for axes, (name, x, variance, labels) in zip(panels, profiles):
        if labels:
            axes.plot(range(len(labels)), variance, "o-", color="#d62728")
            axes.set_xticks(range(len(labels)), labels, rotation=90, fontsize=TEXT_PT)
        else:
            axes.plot(x, variance, color="#d62728")
            axes.xaxis.set_major_locator(MaxNLocator(3))
        axes.set_ylim(0.0, top)
        axes.set_xlabel(name, fontsize=TEXT_PT)
        axes.tick_params(labelsize=TEXT_PT)
    figure.suptitle(title, fontsize=TITLE_PT, wrap=True)
    return _rendered(figure)


def _rendered(figure: Figure) -> Rendered:
    return Rendered(figure)


def arm_colours(arms: list[str]) -> dict[str, str]:
    """One colour per arm, the same in every figure of a report."""
    palette = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"]
    return {arm: palette[i % len(palette)] for i, arm in enumerate(arms)}


def _legend_above(axes, columns: int) -> None:
    """The axes' legend in a row above them, where it hides no data."""
    axes.legend(fontsize=TEXT_PT, loc="lower left", bbox_to_anchor=(0.0, 1.02, 1.0, 0.1), mode="expand", ncol=columns,
                borderaxespad=0.0, frameon=False)


def score_distribution_figure(groups: dict[str, list[int]], paper: dict[int, float] | None, title: str) -> Rendered:
    """Share of runs scored 1, 2, 3 for each group (counts [n1, n2, n3]) with Wilson 95 % intervals, and the
    paper's shares as markers."""
    from analysis.intervals import wilson  # here: statsmodels and scipy.stats cost `trials design` a second to import
    figure = Figure(figsize=(WIDTH_IN, 4.0), layout="constrained")
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
            axes.text(where, -1.5, str(count), ha="center", va="top", fontsize=TEXT_PT, color=colours[group])
    if paper is not None:
        axes.scatter(range(3), [paper[s] for s in (1, 2, 3)], marker="D", color="black", zorder=3, label="paper")
    axes.set_xticks(range(3), ["1: collision", "2: unnatural", "3: natural"], fontsize=TEXT_PT)
    axes.tick_params(axis="x", pad=16)
    axes.tick_params(labelsize=TEXT_PT)
    axes.set_ylabel("% of runs (Wilson 95 % interval)", fontsize=TEXT_PT)
    axes.set_ylim(0, 105)
    _legend_above(axes, len(groups) + (paper is not None))
    figure.suptitle(title, fontsize=TITLE_PT)
    return _rendered(figure)


def trajectories_figure(panels: list[tuple[str, str, np.ndarray, list[np.ndarray]]], colours: dict[str, str], arm_word: str) -> Rendered:
    """Small multiples, one panel per run: (title, arm, robot path (n, 2), pedestrian paths [(m, 2)]); robots coloured by arm.

    Four panels a row, a report column wide, titles and tick labels at the body text's size; the panels share
    their axes, so only the outer ones carry tick labels."""
    columns = min(TRAJECTORY_COLUMNS, max(len(panels), 1))
    rows = max(1, -(-len(panels) // columns))
    every = [p for _, _, robot, peds in panels for p in [robot, *peds] if len(p)]
    points = np.vstack(every) if every else np.zeros((1, 2))
    low, high = points.min(axis=0) - 0.5, points.max(axis=0) + 0.5
    aspect = float(np.clip((high[1] - low[1]) / (high[0] - low[0]), 0.3, 1.5))
    panel = (WIDTH_IN - 0.6) / TRAJECTORY_COLUMNS
    figure = Figure(figsize=(WIDTH_IN, rows * (panel * aspect + 0.5) + 1.2), layout="constrained")
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
        axes.xaxis.set_major_locator(MaxNLocator(3))
        axes.yaxis.set_major_locator(MaxNLocator(3))
        axes.set_title(title, fontsize=TEXT_PT, wrap=True)
        axes.tick_params(labelsize=TEXT_PT)
    figure.suptitle(f"Robot (colour: {arm_word}) and pedestrian (grey) paths, m; markers at the end", fontsize=TEXT_PT, wrap=True)
    handles = [Line2D([], [], color=colour, linewidth=1.6, label=arm) for arm, colour in colours.items()]
    handles.append(Line2D([], [], color="0.6", linewidth=0.8, label="pedestrian"))
    figure.legend(handles=handles, loc="outside lower center", fontsize=TEXT_PT, ncol=len(handles), frameon=False)
    return _rendered(figure)


def shares_figure(rows: list[tuple[int, dict[str, tuple[float, float, float]]]], paper: dict[str, dict[int, float]] | None, title: str) -> Rendered:
    """Share judged compliant (with its interval) per arm for runs with >= k pedestrians: rows of (k, arm -> (share, low, high))."""
    arms = list(rows[0][1]) if rows else []
    colours = arm_colours(arms)
    figure = Figure(figsize=(WIDTH_IN, 4.0), layout="constrained")
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
    axes.tick_params(labelsize=TEXT_PT)
    axes.set_ylabel("% judged socially compliant", fontsize=TEXT_PT)
    axes.set_ylim(0, 105)
    _legend_above(axes, 2)
    figure.suptitle(title, fontsize=TITLE_PT)
    return _rendered(figure)


def min_distance_figure(points: list[tuple[str, float, float]], arms: list[str], title: str, intimate_m: float) -> Rendered:
    """Minimum gap of each run against its pedestrian count, one colour per arm: points (arm, pedestrians, gap).

    The counts are categories (the design's levels), evenly spaced whatever their values, each arm's runs
    side by side within a category. The intimate-distance line is named in the legend, where no point covers it."""
    colours = arm_colours(arms)
    figure = Figure(figsize=(WIDTH_IN, 4.0), layout="constrained")
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
    axes.axhline(intimate_m, color="0.4", linestyle=":", linewidth=1.2, label=f"intimate distance {intimate_m:g} m")
    axes.set_xticks(range(len(levels)), [str(level) for level in levels])
    axes.set_xlim(-0.5, len(levels) - 0.5)
    axes.tick_params(labelsize=TEXT_PT)
    axes.set_xlabel("pedestrians", fontsize=TEXT_PT)
    axes.set_ylabel("minimum gap to a pedestrian (m)", fontsize=TEXT_PT)
    axes.set_ylim(bottom=0)
    _legend_above(axes, len(arms) + 1)
    figure.suptitle(title, fontsize=TITLE_PT)
    return _rendered(figure)


#: Residual panels a row.
RESIDUAL_COLUMNS = 2


def residuals_figure(panels: list[tuple[str, tuple[float, ...], tuple[float, ...], tuple[bool, ...]]]) -> Rendered:
    """Residual against fitted value, one panel per fit, two a row: (title, fitted, residuals, flagged); flagged
    runs (censored values) drawn as open red triangles."""
    columns = min(RESIDUAL_COLUMNS, max(len(panels), 1))
    rows = max(1, -(-len(panels) // columns))
    figure = Figure(figsize=(WIDTH_IN, 2.9 * rows), layout="constrained")
    grid = figure.subplots(rows, columns, squeeze=False)
    for axes in grid.flat[len(panels):]:
        axes.set_visible(False)
    for axes, (title, fitted, residuals, flagged) in zip(grid.flat, panels):
        x, y, marked = np.asarray(fitted), np.asarray(residuals), np.asarray(flagged, dtype=bool)
        axes.plot(x[~marked], y[~marked], "o", color="#1f77b4", markersize=4)
        if marked.any():
            axes.plot(x[marked], y[marked], "^", markerfacecolor="none", markeredgecolor="#d62728", markersize=6, label="censored (timeout)")
            axes.legend(fontsize=TEXT_PT)
        axes.axhline(0.0, color="0.5", linewidth=0.8)
        axes.set_title(title, fontsize=TEXT_PT)
        axes.set_xlabel("fitted", fontsize=TEXT_PT)
        axes.set_ylabel("residual", fontsize=TEXT_PT)
        axes.xaxis.set_major_locator(MaxNLocator(4))
        axes.tick_params(labelsize=TEXT_PT)
    return _rendered(figure)
