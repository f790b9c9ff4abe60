"""Bad input to `trials score`, `trials respond` and `trials report`: one-line errors, exit 2, nothing changed."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from analysis.records import SIMULATED
from tests.support.registration import recorded_digest
from tests.support.synthetic_study import design, run_all
from trials.cli import main
from trials.responses import read_responses
from trials.simulated_participants import simulate_run
from trials.study import StudyFolder


@pytest.fixture(scope="module")
def template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The blinded A/B plan with its first 12 runs finished."""
    root = tmp_path_factory.mktemp("bad") / "study"
    run_all(design(root), limit=12)
    return root


@pytest.fixture
def study(template: Path, tmp_path: Path) -> Path:
    return Path(shutil.copytree(template, tmp_path / "study"))


def _codes(root: Path) -> tuple[list[str], list[str]]:
    """(finished, unfinished) run codes."""
    plan = StudyFolder(root).read_plan()
    return [r["run_code"] for r in plan[:12]], [r["run_code"] for r in plan[12:]]


def _snapshot(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(root.rglob("*")) if p.is_file()}


def _fails(args: list[str], root: Path, capsys: pytest.CaptureFixture[str], *expected: str) -> None:
    """The command exits 2 with one `error:` line holding every expected piece, and changes no file."""
    before = _snapshot(root)
    capsys.readouterr()
    assert main([*args, "--study", str(root)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    for piece in expected:
        assert piece in err, (piece, err)
    assert _snapshot(root) == before


def test_score_rejects_bad_input(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    finished, unfinished = _codes(study)
    _fails(["score", "QQQQQ", "3"], study, capsys, "unknown run code(s) QQQQQ")
    _fails(["score", finished[0], "4"], study, capsys, "score must be 1, 2 or 3, got '4'")
    _fails(["score", finished[0], "0"], study, capsys, "score must be 1, 2 or 3")
    _fails(["score", unfinished[0], "3"], study, capsys, f"not finished yet: {unfinished[0]}")
    _fails(["score", finished[0]], study, capsys, "give a run code and a score")
    sheet = study.parent / "sheet.csv"
    sheet.write_text(f"run_code,score\n{finished[0]},3\nQQQQQ,2\nWWWWW,1\n")
    _fails(["score", "--import", str(sheet)], study, capsys, "unknown run code(s) QQQQQ, WWWWW")
    sheet.write_text(f"run_code,score\n{finished[0]},3\n{finished[1]},5\n")
    _fails(["score", "--import", str(sheet)], study, capsys, "line 3 of sheet.csv: score must be 1, 2 or 3, got '5'")
    sheet.write_text("code,score\nAAAAA,3\n")
    _fails(["score", "--import", str(sheet)], study, capsys, "missing column(s) run_code")
    assert not (study / "scores.csv").exists()


def test_score_import_records_and_skips_repeats(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    finished, _ = _codes(study)
    sheet = study.parent / "sheet.csv"
    sheet.write_text(f"run_code,score,scorer,note\n{finished[0]},3,ana,\n{finished[1]},2,ana,hesitant\n")
    assert main(["score", "--import", str(sheet), "--study", str(study)]) == 0
    assert main(["score", "--import", str(sheet), "--study", str(study)]) == 0
    assert "Imported 0 score(s)" in capsys.readouterr().out
    rows = (study / "scores.csv").read_text().splitlines()
    assert rows[0] == "run_code,score,scorer,note,recorded_utc" and len(rows) == 3
    assert rows[2].startswith(f"{finished[1]},2,ana,hesitant,")


def test_respond_rejects_bad_input(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    finished, unfinished = _codes(study)
    _fails(["respond", finished[0], "P1", "maybe"], study, capsys, "compliant must be yes or no, got 'maybe'")
    _fails(["respond", "QQQQQ", "P1", "yes"], study, capsys, "unknown run code(s) QQQQQ")
    _fails(["respond", unfinished[0], "P1", "no"], study, capsys, f"not finished yet: {unfinished[0]}")
    _fails(["respond", finished[0], "P1", "yes", "--simulate"], study, capsys, "not several")
    _fails(["respond", "--simulate", "--participants", "0"], study, capsys, "argument --participants: expected a whole number from 1 to 1000, got '0'")
    _fails(["respond", "--seed", "3"], study, capsys, "--participants and --seed go with --simulate")
    _fails(["respond", "--allow-simulated"], study, capsys, "--allow-simulated goes with --simulate or --import")
    sheet = study.parent / "judgments.csv"
    sheet.write_text(f"run_code,participant,compliant\n{finished[0]},P1,yes\nZZZZZ,P1,no\n")
    _fails(["respond", "--import", str(sheet)], study, capsys, "unknown run code(s) ZZZZZ")
    sheet.write_text(f"run_code,participant,compliant,source\n{finished[0]},P1,yes,robot\n")
    _fails(["respond", "--import", str(sheet)], study, capsys, "line 2 of judgments.csv: source must be human or simulated")
    assert not (study / "responses.csv").exists()


def test_respond_records_and_simulates(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    finished, _ = _codes(study)
    root = str(study)
    assert main(["respond", finished[0], "P1", "YES", "--study", root]) == 0
    assert main(["respond", finished[0], "P1", "no", "--study", root]) == 0
    assert "replaces their earlier judgment" in capsys.readouterr().out
    assert main(["respond", "--simulate", "--seed", "9", "--study", root]) == 0
    out = capsys.readouterr().out
    responses = read_responses(study / "responses.csv")
    simulated = [r for r in responses if r.source == SIMULATED]
    # Run 1 had judgments already; the other 11 finished runs get one per pedestrian, with the seed.
    assert {r.run_code for r in simulated} == set(finished[1:])
    assert all(r.seed == 9 for r in simulated)
    assert f"Simulated {len(simulated)} judgment(s) of 11 run(s) with seed 9" in out
    assert main(["respond", "--simulate", "--seed", "9", "--study", root]) == 0
    assert "Every finished run already has judgments." in capsys.readouterr().out
    assert read_responses(study / "responses.csv") == responses


def test_simulate_run_for_the_runner(study: Path, template: Path, tmp_path: Path) -> None:
    finished, _ = _codes(study)
    folder = StudyFolder(study)
    first = simulate_run(folder, finished[2], seed=4)
    assert first and all(r.run_code == finished[2] and r.source == SIMULATED and r.seed == 4 for r in first)
    assert simulate_run(folder, finished[2], seed=4) == []
    again = simulate_run(StudyFolder(Path(shutil.copytree(template, tmp_path / "again"))), finished[2], seed=4)
    assert [(r.participant, r.compliant) for r in again] == [(r.participant, r.compliant) for r in first]


def test_report_refuses_broken_results(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    finished, _ = _codes(study)
    (study / "scores.csv").write_text(f"run_code,score,scorer,note,recorded_utc\n{finished[0]},3,ana,,\nQQQQQ,2,ana,,\nWWWWW,2,ana,,\n")
    _fails(["report"], study, capsys, "scores.csv has scores for unknown run code(s) QQQQQ, WWWWW")
    (study / "scores.csv").write_text(f"run_code,score,scorer,note,recorded_utc\n{finished[0]},7,ana,,\n")
    _fails(["report"], study, capsys, "line 2 of scores.csv: score must be 1, 2 or 3, got '7'")
    (study / "scores.csv").unlink()
    (study / "responses.csv").write_text("run_code,participant,compliant,source,recorded_utc,seed\nQQQQQ,S01,yes,simulated,,1\n")
    _fails(["report"], study, capsys, "responses.csv has judgments for unknown run code(s) QQQQQ")
    (study / "responses.csv").unlink()
    outcomes = study / "outcomes.csv"
    text = outcomes.read_text()
    outcomes.write_text(text + text.splitlines()[1].replace(finished[0], "XXXXX", 1) + "\n")
    _fails(["report"], study, capsys, "outcomes.csv has rows for unknown run code(s) XXXXX")
    outcomes.write_text(text.replace(",goal,", ",arrived,", 1))
    _fails(["report"], study, capsys, "line 2 of outcomes.csv: status must be one of goal, collision, timeout")
    outcomes.write_text(text.splitlines()[0] + "\n")
    _fails(["report"], study, capsys, "no finished runs")
    outcomes.write_text(text)
    digest = recorded_digest(study)
    _fails(["report", "--unblind"], study, capsys, "--unblind needs --commitment HEX")
    _fails(["report", "--unblind", "--commitment", digest], study, capsys, f"only {len(finished)} of 18 runs finished",
           "interim look", "--interim REASON")
    _fails(["report", "--unblind", "--commitment", digest, "--interim", " "], study, capsys, "--interim needs a reason")
    _fails(["report", "--interim", " "], study, capsys, "--interim needs a reason")
    (study / "sealed" / "allocation.json").unlink()
    _fails(["report", "--unblind", "--commitment", digest, "--interim", "a look"], study, capsys, "the sealed key", "is missing")
    assert not (study / "report").exists()


@pytest.mark.slow
def test_an_interim_unblinding_is_recorded_with_its_reason_and_completeness(study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    finished, _ = _codes(study)
    digest = recorded_digest(study)
    reason = "safety review after a collision"
    assert main(["report", "--study", str(study), "--unblind", "--commitment", digest, "--interim", reason]) == 0
    record = json.loads((study / "unblinding.json").read_text())
    (opening,) = record["openings"]
    plan = json.loads((study / "design.json").read_text())["analysis_plan"]["sha256"]  # the plan in force, as committed
    assert opening == {"utc": record["unblinded_utc"][0], "completeness": f"{len(finished)} of 18 runs finished", "interim": reason,
                       "command": "trials report --unblind", "analysis_plan_sha256": plan,
                       "recorded_before": []}  # no person had scored or judged a run yet (the judgments are simulated)
    blinding = json.loads((study / "report" / "report.json").read_text())["blinding"]
    assert (blinding["completeness"], blinding["interim"]) == (opening["completeness"], reason)
    assert f"**Interim unblinding** with {len(finished)} of 18 runs finished, for this reason: {reason}" in (study / "report" / "report.md").read_text()
