"""responses.csv, participants' judgments of runs: its columns (the fields of `analysis.records.Response`,
then one per questionnaire item the study defines in study.toml, only when it defines any), its one reader
(also of files for `trials respond --import`) and its one writer (appends)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from analysis.records import HUMAN, SIMULATED, Response
from designs.questionnaire import LikertItem
from trials.csv_table import (
    FORMULA_STARTS,
    MAX_CODE,
    append_rows,
    code_cell,
    parse_rows,
    read_table,
    record_cells,
    record_columns,
    text_cell,
    utc_cell,
)
from trials.errors import StudyError
from trials.numbers import shown
from trials.outcomes import check_run_codes, finished_codes
from trials.study import RESPONSES, StudyFolder, utc_now

ANSWERS = {"yes": True, "no": False}
#: What a file of judgments must have; source defaults to human, recorded_utc and seed may be absent.
REQUIRED = ("run_code", "participant", "compliant")


def parse_answer(cell: str) -> bool:
    """yes / no (any case) as a bool; ValueError otherwise."""
    answer = ANSWERS.get(cell.strip().lower())
    if answer is None:
        raise ValueError(f"compliant must be yes or no, got {shown(cell)}")
    return answer


def read_responses(path: Path) -> list[Response]:
    """Judgments from a responses.csv-shaped file, in file order ([] when there is none)."""
    return parse_rows(path, read_table(path, REQUIRED), _response)


def read_ratings(path: Path, items: Sequence[LikertItem]) -> list[dict[str, int | None]]:
    """Each row's questionnaire answers (None: not answered), in file order, beside `read_responses`' records."""
    return parse_rows(path, read_table(path, REQUIRED), lambda row: {item.name: _rating(item, row.get(item.name, "")) for item in items})


def append_responses(folder: StudyFolder, responses: Sequence[Response], ratings: Sequence[Mapping[str, int | None]] = ()) -> None:
    """Add judgments to the study's responses.csv, each with its questionnaire answers by item name
    (`ratings`, one mapping per judgment, or none); a new item adds its column, empty in earlier rows."""
    path = folder.path(RESPONSES)
    base = record_columns(Response)
    header = list(read_table(path, REQUIRED).header) or list(base)
    for name in (name for answers in ratings for name in answers):
        if name in base:
            raise StudyError(f"questionnaire item {name!r} has the name of a column of {RESPONSES} of its own")
        if name not in header:
            header.append(name)
    rows = []
    for i, response in enumerate(responses):
        cells = {**record_cells(response), **{k: "" if v is None else str(v) for k, v in (ratings[i] if ratings else {}).items()}}
        rows.append([cells.get(column, "") for column in header])
    append_rows(path, header, rows, widen=True)


def record_response(folder: StudyFolder, code: str, participant: str, answer: str, ratings: Mapping[str, str] = {},
                    items: Sequence[LikertItem] = (), finished: Iterable[str] | None = None) -> tuple[Response, bool]:
    """Check and append one participant's judgment of a finished run (`trials respond CODE P yes`, the
    console's questionnaire) with its answers to the study's questionnaire `items` (a blank answer: none);
    returns it and whether it replaces an earlier judgment of theirs. The finished runs are those with an
    outcome row unless `finished` names them (the console adds runs whose finish the experimenter recorded,
    before their log is played). StudyError for an answer other than yes or no, a rating off its scale, or a
    run not in the plan or not finished."""
    plan_codes = [row["run_code"] for row in folder.read_plan()]
    finished = finished_codes(folder) if finished is None else list(finished)
    try:
        compliant = parse_answer(answer)
        answers = {item.name: _rating(item, ratings.get(item.name, "")) for item in items}
    except ValueError as exc:
        raise StudyError(str(exc)) from None
    check_participant(participant)
    check_run_codes([code], plan_codes, finished, "a judgment")
    earlier = any(r.run_code == code and r.participant == participant and r.source == HUMAN for r in read_responses(folder.path(RESPONSES)))
    response = Response(code, participant, compliant, HUMAN, utc_now())
    append_responses(folder, [response], [answers] if items else ())
    return response, earlier


def check_participant(participant: str) -> None:
    """StudyError unless a participant code is one short line of printable text that a spreadsheet will not take for a
    formula (a leading =, +, - or @ would run as one when responses.csv is opened)."""
    if not participant.strip() or not participant.isprintable() or len(participant) > MAX_CODE or participant != participant.strip():
        raise StudyError(f"a participant code must be 1 to {MAX_CODE} printable characters without surrounding spaces, got {shown(participant)}")
    if participant.startswith(FORMULA_STARTS):
        raise StudyError(f"a participant code must not begin with =, +, - or @ (a spreadsheet would run it as a formula), got {participant!r}")


def _rating(item: LikertItem, cell: str) -> int | None:
    cell = cell.strip()
    if not cell:
        return None
    if not cell.isdigit() or not 1 <= int(cell) <= item.scale:
        raise ValueError(f"{item.name} must be a whole number from 1 to {item.scale}, got {cell!r}")
    return int(cell)


def _response(row: dict[str, str]) -> Response:
    source = row.get("source") or HUMAN
    if source not in (HUMAN, SIMULATED):
        raise ValueError(f"source must be {HUMAN} or {SIMULATED}, got {source!r}")
    seed = row.get("seed", "")
    if seed and not (seed.isascii() and seed.isdigit()):
        raise ValueError(f"seed must be a whole number from 0, got {shown(seed)}")
    return Response(text_cell(row["run_code"], "run_code", MAX_CODE), code_cell(row["participant"], "participant"),
                    parse_answer(row["compliant"]), source, utc_cell(row.get("recorded_utc", "")), int(seed) if seed else None)
