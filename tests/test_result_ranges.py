"""Each column of the results files read with its range demand (issue 43): a hand-edited outcomes.csv, scores.csv or
responses.csv whose cell is out of range is refused in one line naming the file, line and column, exit 2, by every
command that reads it; values at the edge of the range still read."""

from __future__ import annotations

import csv
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.support.console import add_outcome
from trials.cli import main
from trials.errors import StudyError
from trials.outcomes import MAX_RUN_S, read_outcomes
from trials.responses import read_responses
from trials.scores import read_scores

CODE = "NGAC3"  # the first run of the A/B plan with seed 1
LONG = "P" * 10_000
SCORES = "run_code,score,scorer,note,recorded_utc\n"
RESPONSES = "run_code,participant,compliant,source,recorded_utc,seed\n"


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The 18-run blinded A/B plan with one finished run, one score and one judgment of it."""
    root = tmp_path_factory.mktemp("template") / "study"
    assert main(["design", "--ab", "--seed", "1", "--study", str(root)]) == 0
    add_outcome(root, CODE, perception="sim")
    (root / "scores.csv").write_text(SCORES + f"{CODE},2,ana,passed close,2026-05-01T10:05:00+00:00\n")
    (root / "responses.csv").write_text(RESPONSES + f"{CODE},P1,yes,human,2026-05-01T10:06:00+00:00,\n")
    return root


def edit(name: str, column: str, value: str) -> Callable[[Path], None]:
    """Set `column` of the first row of the study's `name` to `value`."""
    def change(study: Path) -> None:
        with (study / name).open(newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
        rows[1][rows[0].index(column)] = value
        with (study / name).open("w", newline="", encoding="utf-8") as handle:
            csv.writer(handle, lineterminator="\n").writerows(rows)
    return change


@dataclass(frozen=True)
class Case:
    name: str
    command: tuple[str, ...]
    change: Callable[[Path], None]
    expected: str


CASES = [
    Case("duration 1e308", ("report",), edit("outcomes.csv", "duration_s", "1e308"),
         "line 2 of outcomes.csv: duration_s must be a number from 0 to 86400, got '1e308'"),
    Case("duration negative", ("status",), edit("outcomes.csv", "duration_s", "-5"),
         "line 2 of outcomes.csv: duration_s must be a number from 0 to 86400, got '-5'"),
    Case("time to goal past a day", ("status",), edit("outcomes.csv", "time_to_goal_s", "90000"),
         "line 2 of outcomes.csv: time_to_goal_s must be a number from 0 to 86400, got '90000'"),
    Case("path length negative", ("report",), edit("outcomes.csv", "path_length_m", "-0.5"),
         "line 2 of outcomes.csv: path_length_m must be a number from 0 to 1e+09, got '-0.5'"),
    Case("dropout above one", ("status",), edit("outcomes.csv", "dropout", "1.5"),
         "line 2 of outcomes.csv: dropout must be a number from 0 to 1, got '1.5'"),
    Case("seed negative", ("status",), edit("outcomes.csv", "seed", "-7"),
         "line 2 of outcomes.csv: seed must be a number from 0 to"),
    Case("finished yesterday", ("report",), edit("outcomes.csv", "finished_utc", "yesterday"),
         "line 2 of outcomes.csv: finished_utc must be an ISO 8601 time such as 2026-05-01T14:03:00+00:00, got 'yesterday'"),
    Case("finished without offset", ("status",), edit("outcomes.csv", "finished_utc", "2026-05-01T10:00:00"),
         "line 2 of outcomes.csv: finished_utc must give its UTC offset"),
    Case("finished empty", ("status",), edit("outcomes.csv", "finished_utc", ""),
         "line 2 of outcomes.csv: finished_utc must be an ISO 8601 time"),
    Case("perception with an escape code", ("status",), edit("outcomes.csv", "perception", "sim\x1b[2J"),
         "line 2 of outcomes.csv: perception must be at most 1000 characters of text"),
    Case("participant of 10,000 characters", ("report",), edit("responses.csv", "participant", LONG),
         "line 2 of responses.csv: participant must be 1 to 40 printable characters, got 'PPPPPPPPPPPPPPPPPPPPPPPP'... (10000 characters)"),
    Case("participant with a tab", ("status",), edit("responses.csv", "participant", "P\t1"),
         "line 2 of responses.csv: participant must be 1 to 40 printable characters, got 'P\\t1'"),
    Case("scorer of 10,000 characters", ("report",), edit("scores.csv", "scorer", LONG),
         "line 2 of scores.csv: scorer must be 1 to 40 printable characters, got 'PPPPPPPPPPPPPPPPPPPPPPPP'... (10000 characters)"),
    Case("scorer as a formula", ("status",), edit("scores.csv", "scorer", "=1+1"),
         "line 2 of scores.csv: scorer must not begin with =, +, - or @"),
    Case("note of 10,000 characters", ("status",), edit("scores.csv", "note", LONG),
         "line 2 of scores.csv: note must be at most 2000 characters of text"),
    Case("scorer given too long", ("score", CODE, "2", "--by", LONG), lambda study: None,
         "the scorer's name must be 1 to 40 printable characters"),
    Case("participant imported too long", ("respond", "--import", "{study}/../sheet.csv"),
         lambda study: (study.parent / "sheet.csv").write_text(f"run_code,participant,compliant\n{CODE},{LONG},yes\n"),
         "line 2 of sheet.csv: participant must be 1 to 40 printable characters"),
]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_a_cell_out_of_range_is_one_line_exit_2_and_writes_nothing(case: Case, template: Path, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    case.change(study)
    before = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file()}
    capsys.readouterr()
    assert main([*(a.format(study=study) for a in case.command), "--study", str(study)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert case.expected in err, err
    assert {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file()} == before


def test_values_at_the_edge_of_their_range_read(template: Path, tmp_path: Path) -> None:
    study = Path(shutil.copytree(template, tmp_path / "study"))
    for column, value in (("duration_s", "86400"), ("time_to_goal_s", "0"), ("dropout", "1"), ("seed", str(2**63 + 1)),
                          ("finished_utc", "2026-05-01T12:00:00+02:00")):
        edit("outcomes.csv", column, value)(study)
    edit("responses.csv", "participant", "Q" * 40)(study)
    edit("scores.csv", "note", "stopped twice,\nthen passed\tclose" + "." * 1900)(study)
    (outcome,) = read_outcomes(study / "outcomes.csv", blind=True)
    assert (outcome.duration_s, outcome.time_to_goal_s, outcome.dropout, outcome.seed) == (MAX_RUN_S, 0.0, 1.0, 2**63 + 1)
    assert outcome.finished_utc == "2026-05-01T12:00:00+02:00"
    assert read_responses(study / "responses.csv")[0].participant == "Q" * 40
    assert read_scores(study / "scores.csv")[0].note.startswith("stopped twice,\nthen passed\tclose.")
    edit("outcomes.csv", "duration_s", "86400.5")(study)
    with pytest.raises(StudyError, match=r"line 2 of outcomes.csv: duration_s must be a number from 0 to 86400, got '86400.5'"):
        read_outcomes(study / "outcomes.csv", blind=True)
