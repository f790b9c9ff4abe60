"""power/power.png and power.svg: each term's power against the plan's runs (model-based lines, closed-loop points
when campaigns ran, with their Monte Carlo intervals), and with closed-loop campaigns the spread of Table II's shares."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from robot_logs.figure_files import BODY_TEXT_PT, FIGURE_WIDTH_IN, Rendered
from trials.atomic import write_files
from trials.power.summary import PlanPower


def power_rendered(powers: Sequence[PlanPower], target: float) -> Rendered:
    """The figure: a report column wide, the legend above the data (the title names only what is drawn), text at the body text's size; the shares' spread
    in a second panel below when campaigns ran."""
    from matplotlib.figure import Figure

    spread = next((p for p in powers if p.shares), None)
    closed_loop = any(p.campaigns for p in powers)
    figure = Figure(figsize=(FIGURE_WIDTH_IN, 8.4 if spread else 4.4), layout="constrained")
    axes = figure.subplots(2 if spread else 1, 1, squeeze=False)[:, 0]
    ax = axes[0]
    runs = [p.runs for p in powers]
    for i, term in enumerate(powers[0].judgments):
        colour = f"C{i % 10}"
        values = [p.judgments[term] for p in powers]
        ax.errorbar(runs, [e.power for e in values], yerr=[[e.power - e.low for e in values], [e.high - e.power for e in values]],
                    color=colour, marker="o", capsize=3, label=term)
        closed = [(p.runs, p.closed_terms[term]) for p in powers if p.campaigns]
        if closed:
            ax.errorbar([r + 0.6 for r, _ in closed], [e.power for _, e in closed],
                        yerr=[[e.power - e.low for _, e in closed], [e.high - e.power for _, e in closed]],
                        color=colour, marker="s", linestyle="none", capsize=3, mfc="white")
    ax.axhline(target, color="grey", linestyle=":", linewidth=1, label=f"target {target:g}")
    ax.set(xlabel="runs in the plan", ylabel="power (judgments, GEE by run)", ylim=(0, 1.02), xticks=runs)
    figure.suptitle("Power by term: model-based (lines)" + (", closed-loop (open squares)" if closed_loop else ""), fontsize=BODY_TEXT_PT + 1)
    ax.tick_params(labelsize=BODY_TEXT_PT)
    ax.legend(fontsize=BODY_TEXT_PT, loc="lower left", bbox_to_anchor=(0.0, 1.08, 1.0, 0.1), mode="expand", ncol=2,
              borderaxespad=0.0, frameon=False)
    if spread:
        ax = axes[1]
        labels, lows, mids, highs = [], [], [], []
        for k, by_name in spread.shares.items():
            for name, s in by_name.items():
                labels.append(f"{name}\n>= {k}")
                lows.append(s["q2.5"])
                mids.append(s["median"])
                highs.append(s["q97.5"])
        xs = range(len(labels))
        ax.errorbar(xs, mids, yerr=[[m - lo for m, lo in zip(mids, lows)], [h - m for m, h in zip(mids, highs)]], fmt="o", capsize=4)
        ax.set_xticks(list(xs), labels)
        ax.tick_params(labelsize=BODY_TEXT_PT)
        ax.set(ylabel="share judged socially compliant", ylim=(0, 1.02))
        ax.set_title(f"Table II shares over {spread.campaigns} campaigns ({spread.runs} runs): median, 95 %", fontsize=BODY_TEXT_PT + 1, wrap=True)
    return Rendered(figure)


def power_figure(powers: Sequence[PlanPower], target: float, path: Path) -> None:
    """Draw the figure and write it atomically to `path` (PNG at the default resolution) and beside it as SVG."""
    write_files(power_rendered(powers, target).files(path.with_suffix("")))
