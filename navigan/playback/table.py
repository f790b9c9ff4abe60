"""Table I: per-column summaries of the episode scores, written as Markdown and CSV beside the paper's."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from navigan.playback.intervals import RESAMPLES, Interval, mean_interval, rate_interval
from navigan.playback.paper import PAPER_COLUMNS, PaperTable
from navigan.playback.protocols import FRAMES, OBSERVED, RECORDED
from navigan.shield import HORIZON
from robot_logs.physical import STEP_S

#: Model name -> Table I column, in the paper's order.
COLUMNS: dict[str, str] = {
    "goal-social-lstm": "Goal",
    "navil2": "L2",
    "navil2-dagger": "L2-dagger",
    "navigan": "NG",
    "navigan-dagger": "NG-dagger",
    "navigan-r": "R",
    "navigan-r-dagger": "R-dagger",
    "navigan-r-evasion": "R+evasion",
    "navigan-r-shield": "R+shield",
    "human": "human",
}

#: The names of the columns in the CSV files: the labels with "-" and "+" as "_", which R and
#: pandas keep as they are.
CSV_NAMES: dict[str, str] = {m: label.replace("-", "_").replace("+", "_") for m, label in COLUMNS.items()}
#: The two aggregations: every episode pooled, and the unweighted mean of the per-split values.
POOLED, SPLIT_MEAN = "all", "split_mean"
#: The rows that get a 95 % interval.
INTERVAL_METRICS = ("S", "C", "A")
#: Per-episode scores written to episodes.csv under names with their units.
EPISODE_UNITS = {"min_distance": "min_distance_m", "time_to_goal": "time_to_goal_s", "path_length": "path_length_m",
                 "irregularity": "irregularity_rad_per_m", "ade": "ade_m"}

#: Said after the paper's source while none of its cells holds a number.
UNTRANSCRIBED = " (no cell transcribed yet: n/a; `trials playback --paper FILE` takes a transcription)"

Scores = Sequence[Mapping[str, Any]]


def _mean(values: list[float]) -> float | None:
    return float(np.mean(values)) if values else None


def _closest(scores: Scores) -> np.ndarray:
    """Each episode's closest approach; an episode with nobody else around counts as infinitely far."""
    return np.array([np.inf if s["min_distance"] is None else s["min_distance"] for s in scores])


@dataclass(frozen=True)
class Metric:
    """A row of the table: its key, label and how it is computed from episode scores."""

    key: str
    label: str
    digits: int
    of: Callable[[Scores], float | None]


METRICS: tuple[Metric, ...] = (
    Metric("S", "S (social score)", 3, lambda s: _mean([e["social_score"] for e in s])),
    Metric("C", "C (comfort rate)", 3, lambda s: _mean([float(e["comfortable"]) for e in s])),
    Metric("A", "A (arrival rate)", 3, lambda s: _mean([float(e["arrived"]) for e in s])),
    Metric("collision_rate", "collision rate", 3, lambda s: _mean([float(e["collided"]) for e in s])),
    Metric("min_distance_median_m", "min distance, median (m)", 2,
           lambda s: float(np.median(_closest(s))) if s else None),
    Metric("min_distance_p10_m", "min distance, 10th percentile (m)", 2,
           lambda s: float(np.percentile(_closest(s), 10)) if s else None),
    Metric("time_to_goal_s", "time to goal (s, arrivals)", 1,
           lambda s: _mean([e["time_to_goal"] for e in s if e["time_to_goal"] is not None])),
    Metric("path_ratio", "path length / recorded (arrivals)", 2,
           lambda s: _mean([e["path_ratio"] for e in s if e["path_ratio"] is not None])),
    Metric("irregularity_rad_per_m", "path irregularity (rad/m)", 2, lambda s: _mean([e["irregularity"] for e in s])),
    Metric("ade_m", "ADE to the recorded path (m)", 2,
           lambda s: _mean([e["ade"] for e in s if e["ade"] is not None])),
    Metric("episodes", "episodes", 0, lambda s: float(len(s))),
)


def summarize(scores: Scores) -> dict[str, float | None]:
    """Every metric of one column over some episodes."""
    return {m.key: m.of(scores) for m in METRICS}


def mean_over_splits(per_split: Sequence[Scores]) -> dict[str, float | None]:
    """Every metric as the unweighted mean of its per-split values (splits where it is undefined left
    out); the episode count is the total."""
    summaries = [summarize(s) for s in per_split if s]
    values = {m.key: _mean([v for s in summaries if (v := s[m.key]) is not None]) for m in METRICS}
    return values | {"episodes": float(sum(len(s) for s in per_split))}


def interval_of(metric: str, per_split: Sequence[Scores], pooled: bool, seed: int) -> Interval:
    """The 95 % interval of S, C or A over the splits' episodes, pooled or as the mean over splits."""
    if metric == "S":
        return mean_interval([[e["social_score"] for e in s] for s in per_split], pooled, seed)
    field_name = {"C": "comfortable", "A": "arrived"}[metric]
    return rate_interval([[bool(e[field_name]) for e in s] for s in per_split], pooled)


def aggregate(scope: str, columns: Sequence[str], per_split: Mapping[str, Sequence[Scores]], seed: int) -> Table:
    """The table of one aggregation (POOLED or SPLIT_MEAN) of each model's per-split episode scores,
    with the 95 % intervals of S, C and A (S's bootstrap seeded with `seed`)."""
    pooled = scope == POOLED
    values = {m: summarize([e for s in per_split[m] for e in s]) if pooled else mean_over_splits(per_split[m])
              for m in columns}
    intervals = {m: {k: interval_of(k, per_split[m], pooled, seed) for k in INTERVAL_METRICS} for m in columns
                 if any(per_split[m])}
    return Table(scope, tuple(columns), values, intervals)


def _cell(value: float | None, digits: int, missing: str = "n/a") -> str:
    return missing if value is None else f"{value:.{digits}f}"


@dataclass(frozen=True)
class Table:
    """Table I over one scope (a split, or all evaluated splits pooled).

    Attributes:
        scope: POOLED, SPLIT_MEAN or the split's name.
        columns: the model names shown, in COLUMNS order.
        values: model -> summary (absent where that column was not evaluated).
        intervals: model -> metric (S, C, A) -> its 95 % interval (low, high); empty for a split's table.
    """

    scope: str
    columns: tuple[str, ...]
    values: Mapping[str, Mapping[str, float | None]]
    intervals: Mapping[str, Mapping[str, Interval]] = field(default_factory=dict)

    def rows(self, paper: PaperTable | None, missing: str = "n/a") -> list[tuple[str, str, list[str]]]:
        """(metric key, source, cells) rows: ours, the ends of our 95 % interval ("ours_low",
        "ours_high") under S, C and A, and under the two aggregations the paper's (`missing` where a
        value is undefined or not transcribed, empty under a column the paper has not)."""
        rows = []
        for metric in METRICS:
            ours = [_cell(self.values[m][metric.key], metric.digits, missing) if m in self.values else "pending"
                    for m in self.columns]
            rows.append((metric.key, "ours", ours))
            if metric.key in INTERVAL_METRICS and self.intervals:
                for end, source in enumerate(("ours_low", "ours_high")):
                    rows.append((metric.key, source, [_cell(self.intervals[m][metric.key][end], metric.digits, missing)
                                                      if m in self.intervals else missing for m in self.columns]))
            if paper is not None and self.scope in (POOLED, SPLIT_MEAN) and metric.key in paper.values:
                row = paper.values[metric.key]
                rows.append((metric.key, "paper", [_cell(row.get(COLUMNS[m]), metric.digits, missing)
                                                   if COLUMNS[m] in PAPER_COLUMNS else "" for m in self.columns]))
        return rows

    def markdown(self, paper: PaperTable | None) -> str:
        labels = {m.key: m.label for m in METRICS}
        lines = ["| | " + " | ".join(COLUMNS[m] for m in self.columns) + " |",
                 "|---" + "|---:" * len(self.columns) + "|"]
        rows = self.rows(paper)
        ends = {(key, source): cells for key, source, cells in rows if source in ("ours_low", "ours_high")}
        for key, source, cells in rows:
            if source == "ours_low":
                cells = [f"{low}-{high}" for low, high in zip(cells, ends[key, "ours_high"])]
                lines.append(f"| {key}, 95 % interval | " + " | ".join(cells) + " |")
            elif source != "ours_high":
                label = labels[key] if source == "ours" else f"{key}, paper"
                lines.append(f"| {label} | " + " | ".join(cells) + " |")
        return "\n".join(lines) + "\n"


def csv_text(tables: Sequence[Table], paper: PaperTable | None, protocol: str) -> str:
    """All tables as one CSV: protocol, scope, metric, source (ours, ours_low, ours_high, paper), then
    one column per model (CSV_NAMES); an undefined or untranscribed value is an empty cell."""
    models = list(dict.fromkeys(m for t in tables for m in t.columns))
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["protocol", "scope", "metric", "source"] + [CSV_NAMES[m] for m in models])
    for table in tables:
        for key, source, cells in table.rows(paper, missing=""):
            by_model = dict(zip(table.columns, cells))
            writer.writerow([protocol, table.scope, key, source] + [by_model.get(m, "") for m in models])
    return out.getvalue()


@dataclass(frozen=True)
class SceneCount:
    """How many episodes a split's test recordings gave, and how many standing pedestrians were left out."""

    split: str
    files: Sequence[str]
    episodes: int
    standing: int


def _weights_cell(about: Mapping[str, Any] | None) -> str:
    if about is None:
        return "recordings"
    state = "" if about.get("finished") else ", still training"
    return f"{about['file']} (epoch {about['kept_epoch']} of {about['epochs']}{state})"


def document(
    tables: Sequence[Table],
    scenes: Sequence[SceneCount],
    weights: Mapping[tuple[str, str], Mapping[str, Any] | None],
    settings: Mapping[str, Any],
    paper: PaperTable,
) -> str:
    """table1.md: the protocol and exact metric definitions, the pooled table and the mean over
    splits each beside the paper's, the episodes per split, the weights used, and one table per split.

    Args:
        tables: the pooled table, the mean over splits, then one per split.
        weights: (split, model) -> the checkpoint's description (None for the recordings).
        settings: gamma, v_pref, collision, distances, seed, limit, subgoal_speed, shield, protocol
            and targets (`Settings.record`).
    """
    columns = tables[0].columns
    limit, speed = settings["limit"], settings["subgoal_speed"]
    pace = f"{speed} m/s"
    if speed == RECORDED:
        pace = "the recorded pedestrian's pace (straight to the goal in 14.4 s)"
    handed = ("the goal itself" if speed is None else
              f"a sub-goal 12 steps ahead at {pace} in the goal's direction (beyond the goal once nearer), "
              "as the networks were trained with goals 12 steps ahead")
    targets = (" (every pedestrian present for 20 consecutive frames, its goal where it leaves if sooner)"
               if settings["targets"] == OBSERVED else " (pedestrians present for 44 consecutive frames)")
    measured = ("the distance to the nearest other pedestrian at the recorded frame that ends step k"
                if settings["distances"] == FRAMES else
                "the closest approach to any other pedestrian during step k, both moving straight")
    lines = [
        "# Table I: long-term playback navigation", "",
        f"Protocol `{settings['protocol']}`: targets `{settings['targets']}`, distances `{settings['distances']}`, "
        f"networks handed {'the goal itself' if speed is None else 'a sub-goal at ' + pace.split(' (')[0]}.", "",
        "Each model walks as one recorded pedestrian of a split's test scene (its first 8 positions "
        "observed) toward its recorded position 36 steps (14.4 s) later" + targets
        + f", among the other pedestrians as recorded; it plans 12 steps every 0.4 s toward {handed}, and walks the first. The "
        "episode ends on arrival (within 0.5 m of the goal) or at the cut-off, 60 steps (24 s). The "
        "human column is the recorded path itself."
        + (f" R+shield walks NaviGAN-R's plan with its first step checked: if, held for {HORIZON} "
           f"steps ({HORIZON * STEP_S:g} s), it would come within {settings['shield']:g} m of anyone's "
           "constant-velocity forecast, it is replaced by the move nearest to it that keeps the "
           "distance (navigan/shield.py)."
           if "navigan-r-shield" in columns else "")
        + (" R+evasion walks NaviGAN-R with its evasion networks, trained beside it on the shield's test: "
           "they keep the plan's first step unless they predict it falls short of the margin, else walk the "
           "move that best trades nearness to the plan against predicted shortfall; nothing is forecast "
           "while walking (navigan/evasion.py)."
           if "navigan-r-evasion" in columns else ""), "",
        f"- S: mean over episodes of sum_k {settings['gamma']:g}^((k-1) * 0.4 s * {settings['v_pref']:g} m/s) "
        f"* r_k, with r_k = -0.25 if the step's closest approach d_k < {settings['collision']:g} m "
        "(collision), else +1 if the step reaches the goal, else -0.1 + d_k/2 if d_k < 0.2 m, else 0 "
        f"(CrowdNav's reward and discount; d_k is {measured}).",
        "- C: fraction of episodes whose d_k never falls below 0.2 m (the reading the "
        "paper's numbers need; its prose states the opposite).",
        "- A: fraction of episodes reaching the goal within 0.5 m before the cut-off.",
        "- 95 % intervals: Wilson's for C and A; for S the 2.5th and 97.5th percentiles of "
        f"{RESAMPLES} bootstrap resamples of the episodes (within each split for the mean over splits), "
        f"seeded with {settings['seed']}. The mean over splits weighs each split equally; its C and A "
        "intervals are Wilson's at the effective number of episodes of that mean.",
        f"- Seed {settings['seed']}" + (f"; first {limit} episodes of each split only" if limit else "") + ".", "",
        "The paper does not say which aggregation its Table I uses; both are shown beside it.", "",
        f"## All splits pooled ({', '.join(c.split for c in scenes)}; {sum(c.episodes for c in scenes)} episodes)",
        "", tables[0].markdown(paper), "",
        "## Mean over splits (each split weighted equally; episodes per split: "
        + ", ".join(f"{c.split} {c.episodes}" for c in scenes) + ")",
        "", tables[1].markdown(paper), "",
        f"The paper's rows: {paper.source.rstrip('.')}{'' if paper.transcribed else UNTRANSCRIBED}.", "",
        "## Episodes per split", "",
        "| split | test recordings | episodes | left out: goal within 0.5 m of the start |",
        "|---|---|---:|---:|",
    ]
    lines += [f"| {c.split} | {', '.join(c.files)} | {c.episodes} | {c.standing} |" for c in scenes]
    lines += ["", "## Weights", "", "| split | " + " | ".join(COLUMNS[m] for m in columns) + " |",
              "|---" * (len(columns) + 1) + "|"]
    lines += [f"| {c.split} | " + " | ".join(_weights_cell(weights[c.split, m]) for m in columns) + " |"
              for c in scenes]
    for table, count in zip(tables[2:], scenes):
        lines += ["", f"## {table.scope} ({count.episodes} episodes)", "", table.markdown(paper)]
    return "\n".join(lines)


def _csv_value(value: Any) -> Any:
    """A score as a spreadsheet reads it: booleans as 0/1, None as an empty cell."""
    if isinstance(value, bool):
        return int(value)
    return "" if value is None else value


def episodes_csv(results: Mapping[tuple[str, str], Scores], protocol: str) -> str:
    """Every episode's scores: protocol, split, model, episode, then each score with its unit in its
    name (EPISODE_UNITS; the walked path left out), booleans as 0/1."""
    first = next(iter(results.values()))[0]
    keys = [k for k in first if k not in ("episode", "path")]
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["protocol", "split", "model", "episode", *(EPISODE_UNITS.get(k, k) for k in keys)])
    for (split, model), scores in results.items():
        for r in scores:
            writer.writerow([protocol, split, model, r["episode"]] + [_csv_value(r[k]) for k in keys])
    return out.getvalue()
