"""One owner per study file: every file name is defined once (trials/study.py), each CSV file's
header is its record's fields and its owner reads back what it wrote, and the run-log reader
names the field a message lacks."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import trials.study
from analysis.records import HUMAN, SIMULATED, HumanScore, Outcome, Response
from robot_logs import run_log as fmt
from robot_logs.errors import LogError
from robot_logs.foxglove_log import FoxgloveWriter
from trials.csv_table import record_columns
from trials.outcomes import Outcomes, columns, read_outcomes
from trials.responses import append_responses, read_responses
from trials.scores import append_scores, read_scores
from trials.study import OUTCOMES, RESPONSES, SCORES, StudyFolder

ROOT = Path(__file__).resolve().parents[1]
PRODUCT = ("designs", "navigan", "robot_logs", "analysis", "trials")
OWNER = ROOT / "trials" / "study.py"
#: Another file that happens to share a study file's name: the report's own figure under report/figures/.
SAME_NAME_ELSEWHERE = {("correlation_map.png", "analysis/report.py")}


def _file_names() -> dict[str, str]:
    """The study's file names as trials/study.py defines them (constant -> name), folders and suffixes left out."""
    return {name: value for name, value in vars(trials.study).items()
            if name.isupper() and isinstance(value, str) and "." in value and not value.startswith(".")}


def _strings(path: Path) -> set[str]:
    return {node.value for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
            if isinstance(node, ast.Constant) and isinstance(node.value, str)}


def test_each_study_file_name_is_defined_once():
    names = _file_names()
    assert {"study.toml", "plan.csv", "outcomes.csv", "scores.csv", "responses.csv", "sealed/allocation.json",
            "unblinding.json", "report/unblinding.json", "runs/.lock"} <= set(names.values())
    elsewhere = []
    for path in sorted(p for package in PRODUCT for p in (ROOT / package).rglob("*.py")):
        if path == OWNER:
            continue
        module = path.relative_to(ROOT).as_posix()
        for text in _strings(path):
            for name in names.values():
                base = name.rsplit("/", 1)[-1]
                path_like = text in (name, base) or (" " not in text and text.endswith("/" + base))
                if path_like and (base, module) not in SAME_NAME_ELSEWHERE:
                    elsewhere.append(f"{module}: {text!r}")
    assert elsewhere == []


def _outcome(code: str, status: str, controller: str | None) -> Outcome:
    return Outcome(run_code=code, status=status, seed=2**62 + 7, perception="positions", duration_s=12.5,
                   time_to_goal_s=12.5 if status == "goal" else None, path_length_m=9.75, min_distance_m=None,
                   time_within_0_5m_s=0.0, time_within_1_2m_s=1.25, collisions=int(status == "collision"),
                   max_deceleration_mps2=0.5, max_jerk_mps3=3.125, path_irregularity_rad_per_m=None,
                   turn_in_place_s=0.0, backing_up_s=0.25, stopped_s=-0.0, controller=controller,
                   finished_utc="2026-01-01T00:00:00+00:00")


@pytest.mark.parametrize("blind", [False, True])
def test_outcomes_round_trip(tmp_path, blind):
    folder = StudyFolder(tmp_path)
    written = [_outcome("AAAAA", "goal", None if blind else "Lattice"), _outcome("BBBBB", "collision", None if blind else "NaviGAN-R")]
    outcomes = Outcomes(folder, blind)
    for outcome in written:
        outcomes.append(outcome)
    header = folder.path(OUTCOMES).read_text(encoding="utf-8").splitlines()[0]
    fields = [f for f in record_columns(Outcome) if not (blind and f == "controller")]
    assert header.split(",") == fields == list(columns(blind))
    assert read_outcomes(folder.path(OUTCOMES), blind) == written
    outcomes.remove(["AAAAA"])
    assert read_outcomes(folder.path(OUTCOMES), blind) == written[1:]


def test_scores_round_trip(tmp_path):
    folder = StudyFolder(tmp_path)
    written = [HumanScore("AAAAA", 3, "ana", "smooth, polite", "2026-01-01T00:00:00+00:00"), HumanScore("BBBBB", 1, "bo", "", "")]
    append_scores(folder, written[:1])
    append_scores(folder, written[1:])
    assert folder.path(SCORES).read_text(encoding="utf-8").splitlines()[0].split(",") == list(record_columns(HumanScore))
    assert read_scores(folder.path(SCORES)) == written


def test_responses_round_trip(tmp_path):
    folder = StudyFolder(tmp_path)
    written = [Response("AAAAA", "P01", True, HUMAN, "2026-01-01T00:00:00+00:00"), Response("AAAAA", "sim-1", False, SIMULATED, "", 17)]
    append_responses(folder, written)
    assert folder.path(RESPONSES).read_text(encoding="utf-8").splitlines()[0].split(",") == list(record_columns(Response))
    assert read_responses(folder.path(RESPONSES)) == written


def test_run_log_reader_names_a_missing_field(tmp_path):
    path = tmp_path / "run.mcap"
    with FoxgloveWriter(path, {fmt.RUN_METADATA: {"run_code": "AAAAA"}}) as log:
        log.write(*fmt.ROBOT_STATE, {"t": 0.0, "x": 0.0, "y": 0.0, "v": 0.0, "w": 0.0}, 0)
    with pytest.raises(LogError, match=f"a {fmt.ROBOT_STATE.name} message lacks field 'theta'"):
        fmt.read_run(path)
