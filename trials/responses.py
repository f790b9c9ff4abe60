"""responses.csv, participants' judgments of runs: its columns (the fields of `analysis.records.Response`),
its one reader (also of files for `trials respond --import`) and its one writer (appends)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from analysis.records import HUMAN, SIMULATED, Response
from trials.csv_table import (
    append_rows,
    parse_rows,
    read_table,
    record_columns,
    record_row,
    utc_cell,
)
from trials.study import RESPONSES, StudyFolder

ANSWERS = {"yes": True, "no": False}
#: What a file of judgments must have; source defaults to human, recorded_utc and seed may be absent.
REQUIRED = ("run_code", "participant", "compliant")


def parse_answer(cell: str) -> bool:
    """yes / no (any case) as a bool; ValueError otherwise."""
    answer = ANSWERS.get(cell.strip().lower())
    if answer is None:
        raise ValueError(f"compliant must be yes or no, got {cell!r}")
    return answer


def read_responses(path: Path) -> list[Response]:
    """Judgments from a responses.csv-shaped file, in file order ([] when there is none)."""
    return parse_rows(path, read_table(path, REQUIRED), _response)


def append_responses(folder: StudyFolder, responses: Sequence[Response]) -> None:
    """Add judgments to the study's responses.csv."""
    header = record_columns(Response)
    append_rows(folder.path(RESPONSES), header, (record_row(r, header) for r in responses))


def _response(row: dict[str, str]) -> Response:
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
    return Response(row["run_code"], row["participant"], parse_answer(row["compliant"]), source, utc_cell(row.get("recorded_utc", "")), parsed_seed)
