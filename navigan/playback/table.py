"""Table I: per-column summaries of the episode scores, written as Markdown and CSV beside the paper's."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

#: Model name -> Table I column, in the paper's order.
COLUMNS: dict[str, str] = {
    "goal-social-lstm": "Goal",
    "navil2": "L2",
    "navil2-dagger": "L2-dagger",
    "navigan": "NG",
    "navigan-dagger": "NG-dagger",
    "navigan-r": "R",
    "navigan-r-dagger": "R-dagger",
    "human": "human",
}

PAPER_FILE = Path(__file__).resolve().parent / "paper_table1.json"

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
    Metric("min_distance_median", "min distance, median (m)", 2,
           lambda s: float(np.median(_closest(s))) if s else None),
    Metric("min_distance_p10", "min distance, 10th percentile (m)", 2,
           lambda s: float(np.percentile(_closest(s), 10)) if s else None),
    Metric("time_to_goal", "time to goal (s, arrivals)", 1,
           lambda s: _mean([e["time_to_goal"] for e in s if e["time_to_goal"] is not None])),
    Metric("path_ratio", "path length / recorded (arrivals)", 2,
           lambda s: _mean([e["path_ratio"] for e in s if e["path_ratio"] is not None])),
    Metric("irregularity", "path irregularity (rad/m)", 2, lambda s: _mean([e["irregularity"] for e in s])),
    Metric("ade", "ADE to the recorded path (m)", 2,
           lambda s: _mean([e["ade"] for e in s if e["ade"] is not None])),
    Metric("episodes", "episodes", 0, lambda s: float(len(s))),
)


def summarize(scores: Scores) -> dict[str, float | None]:
    """Every metric of one column over some episodes."""
    return {m.key: m.of(scores) for m in METRICS}


def paper_values(path: Path = PAPER_FILE) -> dict[str, dict[str, float | None]]:
    """The paper's Table I values, metric -> column label -> value (None where not transcribed)."""
    return json.loads(path.read_text(encoding="utf-8"))["values"]


def _cell(value: float | None, digits: int) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


@dataclass(frozen=True)
class Table:
    """Table I over one scope (a split, or all evaluated splits pooled).

    Attributes:
        scope: "all" or the split's name.
        columns: the model names shown, in COLUMNS order.
        values: model -> summary (absent where that column was not evaluated).
    """

    scope: str
    columns: tuple[str, ...]
    values: Mapping[str, Mapping[str, float | None]]

    def rows(self, paper: Mapping[str, Mapping[str, float | None]]) -> list[tuple[str, str, list[str]]]:
        """(metric key, source, cells) rows: ours, and the paper's under S, C and A for the pooled table."""
        rows = []
        for metric in METRICS:
            ours = [_cell(self.values[m][metric.key], metric.digits) if m in self.values else "pending"
                    for m in self.columns]
            rows.append((metric.key, "ours", ours))
            if self.scope == "all" and metric.key in paper:
                rows.append((metric.key, "paper",
                             [_cell(paper[metric.key].get(COLUMNS[m]), metric.digits) for m in self.columns]))
        return rows

    def markdown(self, paper: Mapping[str, Mapping[str, float | None]]) -> str:
        labels = {m.key: m.label for m in METRICS}
        lines = ["| | " + " | ".join(COLUMNS[m] for m in self.columns) + " |",
                 "|---" + "|---:" * len(self.columns) + "|"]
        for key, source, cells in self.rows(paper):
            label = labels[key] if source == "ours" else f"{key}, paper"
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
        return "\n".join(lines) + "\n"


def csv_text(tables: Sequence[Table], paper: Mapping[str, Mapping[str, float | None]]) -> str:
    """All tables as one CSV: scope, metric, source (ours/paper), then one column per model."""
    models = list(dict.fromkeys(m for t in tables for m in t.columns))
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["scope", "metric", "source"] + [COLUMNS[m] for m in models])
    for table in tables:
        for key, source, cells in table.rows(paper):
            by_model = dict(zip(table.columns, cells))
            writer.writerow([table.scope, key, source] + [by_model.get(m, "") for m in models])
    return out.getvalue()
