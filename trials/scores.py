"""scores.csv, evaluators' 1-2-3 scores of runs: its columns (the fields of `analysis.records.HumanScore`),
its one reader (also of files for `trials score --import`) and its one writer (appends)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from analysis.records import HumanScore
from trials.csv_table import (
    MAX_CODE,
    append_rows,
    code_cell,
    parse_rows,
    read_table,
    record_columns,
    record_row,
    text_cell,
    utc_cell,
)
from trials.errors import StudyError
from trials.numbers import shown
from trials.outcomes import check_run_codes, finished_codes
from trials.study import SCORES, StudyFolder, utc_now

SCORES_ALLOWED = (1, 2, 3)
#: The longest note kept with a score.
MAX_NOTE = 2000
#: What a file of scores must have; scorer, note and recorded_utc may be absent.
REQUIRED = ("run_code", "score")


def parse_score(cell: str) -> int:
    """A 1-2-3 score from text; ValueError otherwise."""
    if cell.strip() not in {str(s) for s in SCORES_ALLOWED}:
        raise ValueError(f"score must be 1, 2 or 3, got {shown(cell)}")
    return int(cell)


def read_scores(path: Path) -> list[HumanScore]:
    """Human scores from a scores.csv-shaped file, in file order ([] when there is none)."""
    return parse_rows(path, read_table(path, REQUIRED), _score)


def append_scores(folder: StudyFolder, scores: Sequence[HumanScore]) -> None:
    """Add scores to the study's scores.csv."""
    header = record_columns(HumanScore)
    append_rows(folder.path(SCORES), header, (record_row(s, header) for s in scores))


def record_score(folder: StudyFolder, code: str, score: str, scorer: str, note: str) -> HumanScore:
    """Check and append one evaluator's score of a finished run (`trials score CODE SCORE`, the console's
    score form); StudyError for a score other than 1, 2 or 3, or a run not in the plan or not finished."""
    plan_codes, finished = [row["run_code"] for row in folder.read_plan()], finished_codes(folder)
    try:
        value = parse_score(score)
        code_cell(scorer, "the scorer's name")
        text_cell(note, "the note", MAX_NOTE)
    except ValueError as exc:
        raise StudyError(str(exc)) from None
    check_run_codes([code], plan_codes, finished, "a score")
    record = HumanScore(code, value, scorer, note, utc_now())
    append_scores(folder, [record])
    return record


def _score(row: dict[str, str]) -> HumanScore:
    scorer = row.get("scorer", "")  # absent from an imported file: `trials score --import` fills in the login name
    return HumanScore(text_cell(row["run_code"], "run_code", MAX_CODE), parse_score(row["score"]),
                      code_cell(scorer, "scorer") if scorer else scorer, text_cell(row.get("note", ""), "note", MAX_NOTE),
                      utc_cell(row.get("recorded_utc", "")))
