"""A field study (a [robot] table, or a run driven live or played from a robot log) never gets simulated runs or
simulated judgments unless asked for by name: `trials run`, `trials respond --simulate` and `trials respond --import` of
simulated judgments refuse with one line and exit 2, and `--allow-simulated` lets them."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from trials.cli import main
from trials.commands.status import redo
from trials.outcomes import read_outcomes
from trials.responses import read_responses
from trials.study import OUTCOMES, RESPONSES, StudyFolder
from trials.study_status import study_status


def codes(study: Path) -> list[str]:
    return [row["run_code"] for row in StudyFolder(study).read_plan()]


def test_a_study_with_a_robot_table_is_not_simulated_unless_asked(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--runs", "6", "--seed", "3", "--robot", "ros1://127.0.0.1:11311", "--study", str(study), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["run", "--study", str(study), "--only", codes(study)[0], "--quiet"]) == 2
    error = capsys.readouterr().err.strip()
    assert error.startswith(f"error: {study} is a field study ({study / 'study.toml'} has a [robot] table")
    assert "refusing to simulate run" in error and "--allow-simulated" in error and "\n" not in error
    assert not (study / OUTCOMES).exists()
    assert main(["respond", "--simulate", "--study", str(study)]) == 2
    assert "refusing to simulate participants' judgments" in capsys.readouterr().err


@pytest.mark.slow
def test_allow_simulated_simulates_a_run_and_its_judgments_in_a_field_study(tmp_path):
    study = tmp_path / "s"
    assert main(["design", "--runs", "6", "--seed", "3", "--robot", "ros1://127.0.0.1:11311", "--study", str(study), "--quiet"]) == 0
    first = codes(study)[0]
    assert main(["run", "--study", str(study), "--only", first, "--allow-simulated", "--quiet"]) == 0
    (row,) = read_outcomes(study / OUTCOMES, False)
    assert (row.run_code, row.perception) == (first, "positions")
    assert {r.run_code for r in read_responses(study / RESPONSES)} == {first}


@pytest.mark.slow
def test_a_study_with_a_played_log_is_a_field_study(tmp_path, robot_logs_dir, capsys):
    study = tmp_path / "s"
    assert main(["design", "--runs", "6", "--seed", "3", "--study", str(study), "--quiet"]) == 0
    first, second = codes(study)[:2]
    assert main(["run", "--study", str(study), "--from-log", str(robot_logs_dir / "stationary_ros1.bag"), "--start", "15",
                 "--duration", "6", "--only", first, "--quiet"]) == 0
    capsys.readouterr()
    assert main(["run", "--study", str(study), "--only", second, "--quiet"]) == 2
    assert f"its run {first} was played from a robot log" in capsys.readouterr().err
    assert main(["respond", "--simulate", "--study", str(study)]) == 2
    assert not (study / RESPONSES).exists()
    # Imported judgments obey the same rule: people's pass, simulated ones only when asked for by name.
    sheet = tmp_path / "judgments.csv"
    sheet.write_text(f"run_code,participant,compliant,source\n{first},P1,yes,human\n{first},S1,no,simulated\n")
    capsys.readouterr()
    assert main(["respond", "--import", str(sheet), "--study", str(study)]) == 2
    error = capsys.readouterr().err.strip()
    assert f"refusing to import 1 simulated judgment(s) from {sheet} (source simulated, first on line 3)" in error and "\n" not in error
    assert not (study / RESPONSES).exists()
    assert main(["respond", "--import", str(sheet), "--study", str(study), "--allow-simulated"]) == 0
    assert [(r.participant, r.source) for r in read_responses(study / RESPONSES)] == [("P1", "human"), ("S1", "simulated")]
    (study / RESPONSES).unlink()
    assert main(["respond", "--simulate", "--study", str(study), "--allow-simulated", "--seed", "1"]) == 0
    assert {r.run_code for r in read_responses(study / RESPONSES)} == {first}


def test_status_suggests_only_what_the_study_can_do_again(tmp_path, capsys):
    study = tmp_path / "s"
    assert main(["design", "--runs", "6", "--seed", "3", "--robot", "ros1://127.0.0.1:11311", "--study", str(study), "--quiet"]) == 0
    status = study_status(StudyFolder(study))
    assert status.field is not None and "[robot] table" in status.field
    assert redo(status) == "`trials run --robot ros1://127.0.0.1:11311` drives them again"
    assert redo(replace(status, robot=None)).startswith("attach their logs in `trials serve`")
    assert redo(replace(status, robot=None, field=None)) == "the next `trials run` redoes them"
