"""The paper's Table I values, read from a transcription file and checked cell by cell.

The shipped file (`paper_table1.json`) holds the paper's 24 values, read from its LaTeX source;
`trials playback --paper FILE` takes another transcription (null for a cell left out) without editing the package.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from navigan.errors import NaviganError

PAPER_FILE = Path(__file__).resolve().parent / "paper_table1.json"
#: The paper's Table I columns (ours adds R+shield, which the paper has not).
PAPER_COLUMNS: tuple[str, ...] = ("Goal", "L2", "L2-dagger", "NG", "NG-dagger", "R", "R-dagger", "human")
#: The paper's rows; C and A are fractions of episodes.
PAPER_METRICS: tuple[str, ...] = ("S", "C", "A")
RATES = ("C", "A")


@dataclass(frozen=True)
class PaperTable:
    """A transcription of the paper's Table I.

    Attributes:
        source: where the numbers come from (printed under the table).
        values: metric (S, C, A) -> column label -> value, None where not transcribed.
    """

    source: str
    values: Mapping[str, Mapping[str, float | None]]

    @property
    def transcribed(self) -> int:
        """How many cells hold a number."""
        return sum(v is not None for row in self.values.values() for v in row.values())


def _cell(value: Any, where: str, metric: str) -> float | None:
    """One cell: null, or a finite number (a fraction in [0, 1] for C and A)."""
    if value is None:
        return None
    number = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if metric in RATES and not (number and 0 <= value <= 1):
        raise NaviganError(f"{where}: expected null or a fraction in [0, 1], got {json.dumps(value)}")
    if not number:
        raise NaviganError(f"{where}: expected null or a number, got {json.dumps(value)}")
    return float(value)


def load_paper(path: Path = PAPER_FILE) -> PaperTable:
    """Read and check a transcription: {"source": text, "values": {metric: {column: number or null}}}.

    Raises:
        NaviganError: one line naming the file and the field that is wrong and what was expected.
    """
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise NaviganError(f"cannot read the paper's table {path}: {exc}") from exc
    if not isinstance(data, dict) or not isinstance(data.get("source"), str) or not data["source"].strip():
        raise NaviganError(f"{path}: expected an object with a non-empty \"source\" text and \"values\"")
    values = data.get("values")
    if not isinstance(values, dict):
        raise NaviganError(f"{path}: \"values\": expected an object of metrics {', '.join(PAPER_METRICS)}")
    table: dict[str, dict[str, float | None]] = {}
    for metric, row in values.items():
        if metric not in PAPER_METRICS:
            raise NaviganError(f"{path}: values.{metric}: unknown metric; expected {', '.join(PAPER_METRICS)}")
        if not isinstance(row, dict):
            raise NaviganError(f"{path}: values.{metric}: expected an object of columns {', '.join(PAPER_COLUMNS)}")
        unknown = [c for c in row if c not in PAPER_COLUMNS]
        if unknown:
            raise NaviganError(f"{path}: values.{metric}.{unknown[0]}: unknown column; expected "
                               f"{', '.join(PAPER_COLUMNS)}")
        table[metric] = {c: _cell(v, f"{path}: values.{metric}.{c}", metric) for c, v in row.items()}
    return PaperTable(data["source"].strip(), table)
