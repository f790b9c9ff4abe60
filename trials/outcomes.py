"""outcomes.csv, one row per finished run: its columns (the fields of `analysis.records.Outcome`),
its one reader and its one writer.

The runner appends a row as each run finishes; `trials report`, `score` and `respond` read the
rows back. A blinded study's file has no controller column.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

from analysis.records import Outcome, RunMetrics
from trials.atomic import write_text
from trials.csv_table import (
    parse_rows,
    read_table,
    record_cells,
    record_columns,
    record_row,
    table_text,
    text_cell,
    utc_cell,
)
from trials.errors import StudyError
from trials.numbers import number_in, shown
from trials.study import OUTCOMES, PLAN, StudyFolder

CONTROLLER = "controller"
STATUSES = ("goal", "collision", "timeout")
#: The settings columns (`trials.run_settings`), last; files written before them lack them and still read.
SETTINGS = ("noise_std_m", "dropout", "timeout_s", "weights")


def columns(blind: bool, settings: bool = True) -> tuple[str, ...]:
    """The header of outcomes.csv for a blind or an open study (without `settings`: as written before
    the settings columns existed)."""
    return tuple(c for c in record_columns(Outcome) if not (blind and c == CONTROLLER) and (settings or c not in SETTINGS))


def outcome_cells(record: Outcome | RunMetrics) -> dict[str, str]:
    """An outcome's columns (or just its metrics') as outcomes.csv writes them (3 decimals; empty for no value)."""
    return record_cells(record)


def read_outcomes(path: Path, blind: bool | None = None) -> list[Outcome]:
    """The rows of an outcomes.csv in the order runs finished ([] when there is none).

    With `blind` given, the header must be exactly that of a blinded or an open study (with or without
    the settings columns; rows without them have no settings recorded, and the next write adds them).
    """
    table = read_table(path, [c for c in columns(blind=False, settings=False) if c != CONTROLLER])
    if blind is not None and table.header and table.header not in (columns(blind), columns(blind, settings=False)):
        what = "a blinded" if blind else "an open"
        raise StudyError(f"{path} has the columns {','.join(table.header)}, not those of {what} study ({','.join(columns(blind))})")
    return parse_rows(path, table, _outcome)


def outcomes_text(outcomes: Iterable[Outcome], blind: bool) -> str:
    """The content of outcomes.csv: the header, then one line per run."""
    header = columns(blind)
    return table_text(header, (record_row(o, header) for o in outcomes))


def finished_codes(folder: StudyFolder) -> list[str]:
    """The run codes with a row in the study's outcomes.csv."""
    return [o.run_code for o in read_outcomes(folder.path(OUTCOMES))]


def check_run_codes(codes: Iterable[str], plan_codes: Iterable[str], finished: Iterable[str], what: str) -> None:
    """StudyError listing codes that are not in the plan, or whose runs have not finished."""
    codes = list(dict.fromkeys(codes))
    planned, done = set(plan_codes), set(finished)
    unknown = [c for c in codes if c not in planned]
    if unknown:
        raise StudyError(f"{what} for unknown run code(s) {', '.join(unknown)}: not in {PLAN}")
    pending = [c for c in codes if c not in done]
    if pending:
        raise StudyError(f"{what} for run(s) not finished yet: {', '.join(pending)} (no row in {OUTCOMES})")


class Outcomes:
    """A study's outcomes.csv while it runs: its checked rows, and atomic appends and removals. Rows are kept in plan
    order, whatever order the runs finish in: with several workers, the order runs finish in times them, and so would
    tell a blinded study's faster controller."""

    def __init__(self, folder: StudyFolder, blind: bool) -> None:
        self.path, self.blind = folder.path(OUTCOMES), blind
        self.rows = read_outcomes(self.path, blind)
        self._order = {row["run_code"]: k for k, row in enumerate(folder.read_plan() if folder.path(PLAN).exists() else [])}

    @property
    def finished(self) -> set[str]:
        return {row.run_code for row in self.rows}

    def append(self, outcome: Outcome) -> None:
        self.rows.append(outcome)
        self.rows.sort(key=lambda row: self._order.get(row.run_code, len(self._order)))  # stable: a later duplicate stays later
        write_text(self.path, outcomes_text(self.rows, self.blind))

    def remove(self, codes: Sequence[str]) -> None:
        gone = set(codes)
        self.rows = [row for row in self.rows if row.run_code not in gone]
        write_text(self.path, outcomes_text(self.rows, self.blind))


#: No run outlasts a day: a longer time in a `_s` column is damage, not data.
MAX_RUN_S = 86_400.0
#: The range of each number column whose range is not [0, MAX_RUN_S] (a time, `_s`) or [0, MAX_NUMBER].
RANGES = {"dropout": (0.0, 1.0), "seed": (0.0, 2.0**64 - 1), "collisions": (0.0, 1e6)}
#: Any other measure (a path length, a deceleration): finite and non-negative, and far below what a spreadsheet
#: mangles.
MAX_NUMBER = 1e9
#: The longest text cell (run code, perception, controller, weights).
MAX_TEXT = 1000


def _outcome(row: dict[str, str]) -> Outcome:
    """A row as its record, each cell checked against its field's type and range."""
    values: dict[str, Any] = {}
    for spec in fields(Outcome):
        cell = row.get(spec.name, "")
        kind = str(spec.type)
        if spec.name == "status" and cell not in STATUSES:
            raise ValueError(f"status must be one of {', '.join(STATUSES)}, got {shown(cell)}")
        if spec.name == "finished_utc":
            values[spec.name] = utc_cell(cell, spec.name, required=True)
        elif kind.startswith("str"):
            text = text_cell(cell, spec.name, MAX_TEXT)
            values[spec.name] = (text or None) if "None" in kind else text
        elif cell == "" and "None" in kind:
            values[spec.name] = None
        else:
            values[spec.name] = _number(cell, spec.name, whole=kind == "int")
    return Outcome(**values)


def _number(cell: str, column: str, whole: bool) -> int | float:
    low, high = RANGES.get(column, (0.0, MAX_RUN_S if column.endswith("_s") else MAX_NUMBER))
    value = number_in(cell, column, low, high)
    if not whole:
        return value
    if cell.isdigit():
        return int(cell)  # exactly, above 2^53 too
    if value.is_integer():
        return int(value)
    raise ValueError(f"{column} must be a whole number, got {shown(cell)}")
