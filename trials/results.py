"""The study's result tables: outcomes.csv (read), scores.csv and responses.csv (read and appended).

Columns as in docs/study_folder.md. Every read checks the header and each cell it uses and names
the file and line of a bad one; appends rewrite the whole file through a temporary name.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any, TypeVar

from analysis.records import HUMAN, SIMULATED, HumanScore, Outcome, Response
from trials.atomic import write_text
from trials.errors import StudyError
from trials.study import OUTCOMES, RESPONSES, SCORES, StudyFolder

SCORE_COLUMNS = ("run_code", "score", "scorer", "note", "recorded_utc")
RESPONSE_COLUMNS = ("run_code", "participant", "compliant", "source", "recorded_utc", "seed")
OUTCOME_STATUSES = ("goal", "collision", "timeout")
SCORES_ALLOWED = (1, 2, 3)
ANSWERS = {"yes": True, "no": False}

Row = TypeVar("Row")


def read_table(path: Path, required: Sequence[str]) -> list[tuple[int, dict[str, str]]]:
    """(line number, row) of a CSV file with a header; StudyError when a required column is missing."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        return []
    except UnicodeDecodeError as exc:
        raise StudyError(f"{path} is not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    reader = csv.DictReader(io.StringIO(text))
    missing = [c for c in required if c not in (reader.fieldnames or [])]
    if missing:
        raise StudyError(f"{path}: missing column(s) {', '.join(missing)} (expected {', '.join(required)})")
    return [(reader.line_num, {k: (v or "").strip() for k, v in row.items() if k is not None}) for row in reader]


def parse_rows(path: Path, required: Sequence[str], parse: Callable[[dict[str, str], str], Row]) -> list[Row]:
    """Parse each row with `parse(row, where)`; ValueError from it becomes StudyError naming the line."""
    records = []
    for line, row in read_table(path, required):
        where = f"line {line} of {path.name}"
        try:
            records.append(parse(row, where))
        except ValueError as exc:
            raise StudyError(f"{where}: {exc}") from None
    return records


def _outcome(row: dict[str, str], where: str) -> Outcome:
    values: dict[str, Any] = {}
    for spec in fields(Outcome):
        cell = row.get(spec.name, "")
        kind = str(spec.type)
        if spec.name == "status" and cell not in OUTCOME_STATUSES:
            raise ValueError(f"status must be one of {', '.join(OUTCOME_STATUSES)}, got {cell!r}")
        if kind.startswith("str"):
            values[spec.name] = (cell or None) if "None" in kind else cell
        elif cell == "" and "None" in kind:
            values[spec.name] = None
        else:
            values[spec.name] = _number(cell, spec.name, whole=kind == "int")
    return Outcome(**values)


def _number(cell: str, column: str, whole: bool) -> int | float:
    try:
        value = float(cell)
    except ValueError:
        raise ValueError(f"{column} must be a number, got {cell!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{column} must be a finite number, got {cell!r}")
    if not whole:
        return value
    if cell.lstrip("-").isdigit():
        return int(cell)
    if value.is_integer():
        return int(value)
    raise ValueError(f"{column} must be a whole number, got {cell!r}")


def read_outcomes(folder: StudyFolder) -> list[Outcome]:
    """outcomes.csv in the order runs finished."""
    required = [f.name for f in fields(Outcome) if f.name != "controller"]
    return parse_rows(folder.path(OUTCOMES), required, _outcome)


def parse_score(cell: str) -> int:
    """A 1-2-3 score from text; ValueError otherwise."""
    if cell.strip() not in {str(s) for s in SCORES_ALLOWED}:
        raise ValueError(f"score must be 1, 2 or 3, got {cell!r}")
    return int(cell)


def parse_answer(cell: str) -> bool:
    """yes / no (any case) as a bool; ValueError otherwise."""
    answer = ANSWERS.get(cell.strip().lower())
    if answer is None:
        raise ValueError(f"compliant must be yes or no, got {cell!r}")
    return answer


def _score(row: dict[str, str], where: str) -> HumanScore:
    return HumanScore(row["run_code"], parse_score(row["score"]), row.get("scorer", ""), row.get("note", ""), row.get("recorded_utc", ""))


def _response(row: dict[str, str], where: str) -> Response:
    source = row.get("source") or HUMAN
    if source not in (HUMAN, SIMULATED):
        raise ValueError(f"source must be {HUMAN} or {SIMULATED}, got {source!r}")
    if not row["participant"]:
        raise ValueError("participant is empty")
    seed = row.get("seed", "")
    try:
        parsed_seed = int(seed) if seed else None
    except ValueError:
        raise ValueError(f"seed must be an integer, got {seed!r}") from None
    return Response(row["run_code"], row["participant"], parse_answer(row["compliant"]), source, row.get("recorded_utc", ""), parsed_seed)


def read_scores(path: Path) -> list[HumanScore]:
    """Human scores from a scores.csv-shaped file (scorer, note and recorded_utc may be absent)."""
    return parse_rows(path, ("run_code", "score"), _score)


def read_responses(path: Path) -> list[Response]:
    """Judgments from a responses.csv-shaped file (source defaults to human; recorded_utc and seed may be absent)."""
    return parse_rows(path, ("run_code", "participant", "compliant"), _response)


def check_run_codes(codes: Iterable[str], plan_codes: Iterable[str], finished: Iterable[str], what: str) -> None:
    """StudyError listing codes that are not in the plan, or whose runs have not finished."""
    codes = list(dict.fromkeys(codes))
    planned, done = set(plan_codes), set(finished)
    unknown = [c for c in codes if c not in planned]
    if unknown:
        raise StudyError(f"{what} for unknown run code(s) {', '.join(unknown)}: not in plan.csv")
    pending = [c for c in codes if c not in done]
    if pending:
        raise StudyError(f"{what} for run(s) not finished yet: {', '.join(pending)} (no row in outcomes.csv)")


def append_rows(path: Path, header: Sequence[str], rows: Iterable[Sequence[str]]) -> None:
    """Add rows to a CSV file (creating it with `header`), rewriting it atomically."""
    existing = path.read_text(encoding="utf-8") if path.exists() else ""
    if existing:
        found = next(csv.reader(io.StringIO(existing)), [])
        if tuple(found) != tuple(header):
            raise StudyError(f"{path} has columns {', '.join(found)}; expected {', '.join(header)}")
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    if not existing:
        writer.writerow(header)
    writer.writerows(rows)
    separator = "" if not existing or existing.endswith("\n") else "\n"
    write_text(path, existing + separator + buffer.getvalue())


def append_scores(folder: StudyFolder, scores: Sequence[HumanScore]) -> None:
    rows = [(s.run_code, str(s.score), s.scorer, s.note, s.recorded_utc) for s in scores]
    append_rows(folder.path(SCORES), SCORE_COLUMNS, rows)


def append_responses(folder: StudyFolder, responses: Sequence[Response]) -> None:
    rows = [
        (r.run_code, r.participant, "yes" if r.compliant else "no", r.source, r.recorded_utc, "" if r.seed is None else str(r.seed))
        for r in responses
    ]
    append_rows(folder.path(RESPONSES), RESPONSE_COLUMNS, rows)
