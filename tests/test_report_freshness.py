"""`trials status` judges a report's freshness by the content of the files it was made from, in blinded and open
studies alike: a blinded study's files are stamped to the minute, so times cannot tell."""

from __future__ import annotations

import json

import pytest

from trials.cli import main
from trials.study import REPORT_RECORD, StudyFolder
from trials.study_data import INPUTS_KEY, report_inputs


@pytest.mark.slow
@pytest.mark.parametrize("blinded", [True, False], ids=["blinded", "open"])
def test_a_report_goes_stale_when_runs_are_added_within_the_minute(tmp_path, capsys, blinded):
    study = tmp_path / "s"
    assert main(["design", *(["--ab"] if blinded else ["--runs", "6"]), "--seed", "4", "--study", str(study), "--quiet"]) == 0
    codes = [row["run_code"] for row in StudyFolder(study).read_plan()]
    assert main(["run", "--study", str(study), "--only", codes[0], "--quiet"]) == 0
    assert main(["report", "--study", str(study), "--quiet"]) == 0
    record = json.loads((study / REPORT_RECORD).read_text(encoding="utf-8"))
    assert record[INPUTS_KEY] == report_inputs(StudyFolder(study))
    capsys.readouterr()
    assert main(["status", "--study", str(study)]) == 0
    assert "report: up to date with the data" in capsys.readouterr().out
    assert main(["run", "--study", str(study), "--only", codes[1], "--quiet"]) == 0
    capsys.readouterr()
    assert main(["status", "--study", str(study), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["report"] == "older than the data"
    assert main(["report", "--study", str(study), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["status", "--study", str(study), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["report"] == "current"


def state(study, capsys) -> str:
    capsys.readouterr()
    assert main(["status", "--study", str(study), "--json"]) == 0
    return json.loads(capsys.readouterr().out)["report"]


@pytest.mark.slow
def test_a_report_goes_stale_when_its_rubric_is_edited_or_a_run_log_removed(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--runs", "6", "--seed", "4", "--study", str(study), "--quiet"]) == 0
    codes = [row["run_code"] for row in StudyFolder(study).read_plan()]
    assert main(["run", "--study", str(study), "--only", codes[0], "--only", codes[1], "--quiet"]) == 0
    rubric = tmp_path / "strict.toml"
    rubric.write_text("[rubric]\nintimate_distance_m = 0.8\n")
    assert main(["report", "--study", str(study), "--rubric", str(rubric), "--quiet"]) == 0
    assert state(study, capsys) == "current"
    rubric.write_text("[rubric]\nintimate_distance_m = 0.3\n")  # the rubric the report read, outside the study
    assert state(study, capsys) == "older than the data"
    assert main(["report", "--study", str(study), "--rubric", str(rubric), "--quiet"]) == 0
    assert state(study, capsys) == "current"
    (study / "runs" / f"{codes[1]}.mcap").unlink()
    assert state(study, capsys) == "older than the data"
