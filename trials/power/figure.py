"""power/power.png: each term's power against the plan's runs (model-based lines, closed-loop points, with
their Monte Carlo intervals), and with closed-loop campaigns the spread of Table II's shares."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from trials.atomic import write_files
from trials.power.summary import PlanPower


def power_figure(powers: Sequence[PlanPower], target: float, path: Path) -> None:
    """Draw the figure and write it atomically to `path` (PNG)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spread = next((p for p in powers if p.shares), None)
    fig, axes = plt.subplots(1, 2 if spread else 1, figsize=(11 if spread else 6.5, 4.2), squeeze=False)
    ax = axes[0][0]
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
    ax.axhline(target, color="grey", linestyle=":", linewidth=1)
    ax.set(xlabel="runs in the plan", ylabel="power (judgments, GEE by run)", ylim=(0, 1.02), xticks=runs,
           title="model-based (lines), closed-loop (open squares)")
    ax.legend(fontsize=7, loc="lower right")
    if spread:
        ax = axes[0][1]
        labels, lows, mids, highs = [], [], [], []
        for k, by_name in spread.shares.items():
            for name, s in by_name.items():
                labels.append(f"{name}\n>= {k}")
                lows.append(s["q2.5"])
                mids.append(s["median"])
                highs.append(s["q97.5"])
        xs = range(len(labels))
        ax.errorbar(xs, mids, yerr=[[m - lo for m, lo in zip(mids, lows)], [h - m for m, h in zip(mids, highs)]], fmt="o", capsize=4)
        ax.set_xticks(list(xs), labels, fontsize=7)
        ax.set(ylabel="share judged socially compliant", ylim=(0, 1.02),
               title=f"Table II shares over {spread.campaigns} campaigns ({spread.runs} runs): median, 95 %")
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    plt.close(fig)
    write_files({path: buffer.getvalue()})
