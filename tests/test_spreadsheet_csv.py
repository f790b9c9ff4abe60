"""Results files a spreadsheet re-saved (a UTF-8 byte-order mark, CRLF line ends) still take new rows, and no
participant code can become a spreadsheet formula in responses.csv."""

from __future__ import annotations

import csv

import pytest

from tests.support.synthetic_study import design, run_all
from trials.cli import main
from trials.study import RESPONSES, SCORES


def resave_as_a_spreadsheet(path) -> None:
    text = path.read_text(encoding="utf-8")
    path.write_bytes("\ufeff".encode() + text.replace("\n", "\r\n").encode())


@pytest.fixture
def study(tmp_path):
    folder = design(tmp_path / "study")
    run_all(folder, limit=1)
    return folder


def test_a_re_saved_results_file_takes_new_rows(study):
    code = study.read_plan()[0]["run_code"]
    root = str(study.root)
    assert main(["respond", code, "P01", "yes", "--study", root]) == 0
    assert main(["score", code, "2", "--by", "ana", "--study", root]) == 0
    for name in (RESPONSES, SCORES):
        resave_as_a_spreadsheet(study.path(name))
    assert main(["respond", code, "P02", "no", "--study", root]) == 0
    assert main(["score", code, "3", "--by", "ben", "--note", "second look", "--study", root]) == 0
    responses = list(csv.DictReader(study.path(RESPONSES).open(encoding="utf-8", newline="")))
    assert [(r["participant"], r["compliant"]) for r in responses] == [("P01", "yes"), ("P02", "no")]
    scores = list(csv.DictReader(study.path(SCORES).open(encoding="utf-8", newline="")))
    assert [(s["scorer"], s["score"], s["note"]) for s in scores] == [("ana", "2", ""), ("ben", "3", "second look")]
    for name in (RESPONSES, SCORES):
        data = study.path(name).read_bytes()
        assert not data.startswith(b"\xef\xbb\xbf") and b"\r" not in data


@pytest.mark.parametrize("participant", ["=HYPERLINK(1)", "+1", "-2+3", "@SUM(A1)"])
def test_a_participant_code_that_a_spreadsheet_would_run_is_refused(study, participant, capsys):
    code = study.read_plan()[0]["run_code"]
    capsys.readouterr()
    assert main(["respond", "--study", str(study.root), "--", code, participant, "yes"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "must not begin with =, +, - or @" in error and repr(participant) in error
    assert not study.path(RESPONSES).exists()


def test_an_imported_formula_participant_is_refused_with_its_line(study, tmp_path, capsys):
    code = study.read_plan()[0]["run_code"]
    answers = tmp_path / "answers.csv"
    answers.write_text(f"run_code,participant,compliant\n{code},P01,yes\n{code},=cmd|' /C calc'!A0,no\n", encoding="utf-8")
    capsys.readouterr()
    assert main(["respond", "--import", str(answers), "--study", str(study.root)]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "line 3" in error and "participant must not begin with =, +, - or @" in error
    assert not study.path(RESPONSES).exists()
