"""`trials run` and `trials log show` end to end on a small open study: files, logs, resume, rerun, bad input."""

from __future__ import annotations

import csv
import fcntl
import json
import shutil
from datetime import datetime
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

from robot_logs.figure_files import DEFAULT_DPI
from robot_logs.foxglove_log import FoxgloveReader
from tests.support.run_studies import design_small_study
from trials.cli import main
from trials.outcomes import columns
from trials.runner import run_seed

pytestmark = pytest.mark.slow  # studies run end to end through `trials run`
TOPICS = {
    "/tf": "foxglove.FrameTransform", "/scene": "foxglove.SceneUpdate", "/robot/state": "navtrials.RobotState",
    "/pedestrians/state": "navtrials.Pedestrians", "/perception/pedestrians": "navtrials.Pedestrians",
    "/controller/plan": "navtrials.Plan", "/controller/plan_poses": "foxglove.PosesInFrame", "/events": "navtrials.Event",
}


def rows(study: Path) -> list[dict[str, str]]:
    with (study / "outcomes.csv").open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def plan(study: Path) -> list[dict[str, str]]:
    with (study / "plan.csv").open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("open") / "study"
    design_small_study(folder, blind=False)
    return folder


@pytest.fixture(scope="module")
def finished(template, tmp_path_factory) -> tuple[Path, str]:
    """The open study after one complete `trials run`, and what it printed."""
    study = Path(shutil.copytree(template, tmp_path_factory.mktemp("finished") / "study"))
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["run", "--study", str(study)]) == 0
    return study, out.getvalue()


@pytest.fixture
def study(template, tmp_path) -> Path:
    return Path(shutil.copytree(template, tmp_path / "study"))


def test_every_row_runs_once_in_plan_order(finished):
    study, printed = finished
    table = rows(study)
    assert list(table[0]) == list(columns(blind=False))
    assert [r["run_code"] for r in table] == [r["run_code"] for r in plan(study)]
    for row, planned in zip(table, plan(study)):
        assert row["status"] in ("goal", "collision", "timeout")
        assert row["controller"] == planned["Controller"]
        assert int(row["seed"]) == run_seed(11, row["run_code"])
        assert row["perception"] == "positions"
        assert float(row["duration_s"]) <= 60.0
        assert (row["time_to_goal_s"] == row["duration_s"]) == (row["status"] == "goal")
        assert 0.0 <= float(row["time_within_0_5m_s"]) <= float(row["time_within_1_2m_s"]) <= float(row["duration_s"])
        assert row["collisions"] == str(int(row["status"] == "collision"))
        datetime.fromisoformat(row["finished_utc"])
    assert "6 runs finished" in printed and "6 of 6 plan rows are done" in printed
    assert not list(study.rglob("*.partial")) and not list(study.rglob(".*.tmp"))
    assert not (study / "sealed" / "runs").exists()


def test_each_run_log_follows_the_contract(finished):
    study, _ = finished
    for planned in plan(study):
        log = FoxgloveReader(study / "runs" / f"{planned['run_code']}.mcap")
        assert log.topics == {**TOPICS, "/controller/record": "navtrials.ControllerRecord"}
        meta = log.metadata["run"]
        assert meta["run_code"] == planned["run_code"] and meta["study"] == "small-open"
        assert meta["controller"] == planned["Controller"]
        assert {k: meta[k] for k in ("Pedestrians", "Direction", "Controller", "CrossingDistance")} == {
            k: planned[k] for k in ("Pedestrians", "Direction", "Controller", "CrossingDistance")}
        assert len(json.loads(meta["variation"])) == int(planned["Pedestrians"])
        events = [m.data["event"] for m in log.messages(["/events"])]
        assert events[0] == "start" and events[-1] in ("goal", "collision", "timeout") and len(events) == 2
        states = [m.data for m in log.messages(["/robot/state"])]
        assert states[0]["t"] == 0.0 and np.allclose(np.diff([s["t"] for s in states]), 0.1)  # simulated time, 10 Hz
        plans = [m.data for m in log.messages(["/controller/plan"])]
        assert np.allclose(np.diff([p["t"] for p in plans]), 0.4) and len(plans[0]["waypoints"]) == 12


def test_a_second_run_has_nothing_to_do(finished, capsys):
    study, _ = finished
    before = (study / "outcomes.csv").read_bytes()
    assert main(["run", "--study", str(study)]) == 0
    assert "0 runs finished; 6 of 6 plan rows are done" in capsys.readouterr().out
    assert (study / "outcomes.csv").read_bytes() == before


def test_log_show_prints_the_runs_metrics_and_draws_it(finished, capsys):
    study, _ = finished
    row = rows(study)[0]
    assert main(["log", "show", row["run_code"], "--study", str(study)]) == 0
    out = capsys.readouterr().out
    assert f"run {row['run_code']} of study small-open" in out and f"controller: {row['controller']}" in out
    printed = {line.split()[0]: line.split()[1] for line in out.splitlines() if line.startswith("  ")}
    for column in ("path_length_m", "min_distance_m", "time_within_1_2m_s", "max_deceleration_mps2", "stopped_s"):
        assert float(printed[column]) == pytest.approx(float(row[column]), abs=0.02), column
    png, svg = study / "runs" / f"{row['run_code']}.png", study / "runs" / f"{row['run_code']}.svg"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and b"<svg" in svg.read_bytes()
    assert f"trajectories: {png}, {svg}" in out
    width = mpimg.imread(png).shape[1]
    assert main(["log", "show", row["run_code"], "--study", str(study), "--dpi", str(2 * DEFAULT_DPI)]) == 0
    assert mpimg.imread(png).shape[1] == pytest.approx(2 * width, abs=4)  # the same picture at twice the resolution


def test_rerun_moves_the_old_run_aside_and_reproduces_it(finished, tmp_path, capsys):
    study = Path(shutil.copytree(finished[0], tmp_path / "study"))
    code = next(r["run_code"] for r in rows(study) if r["controller"] == "NaviGAN-R")
    old = next(r for r in rows(study) if r["run_code"] == code)
    assert main(["log", "show", code, "--study", str(study)]) == 0
    assert main(["run", "--rerun", code, "--study", str(study)]) == 0
    assert "moved to" in capsys.readouterr().out
    (aside,) = (study / "superseded").iterdir()
    assert all((aside / "runs" / f"{code}{suffix}").exists() for suffix in (".mcap", ".png", ".svg"))
    assert not (study / "runs" / f"{code}.png").exists() and not (study / "runs" / f"{code}.svg").exists()
    with (aside / "outcomes.csv").open(newline="") as handle:
        assert list(csv.DictReader(handle)) == [old]
    table = rows(study)
    assert len(table) == 6 and [r["run_code"] for r in table] == [r["run_code"] for r in plan(study)]  # back in its place
    new = next(r for r in table if r["run_code"] == code)
    assert {k: v for k, v in new.items() if k != "finished_utc"} == {k: v for k, v in old.items() if k != "finished_utc"}


def test_only_runs_the_rows_named(study, capsys):
    codes = [r["run_code"] for r in plan(study)]
    assert main(["run", "--only", codes[3], codes[1], "--study", str(study)]) == 0
    assert [r["run_code"] for r in rows(study)] == [codes[1], codes[3]]
    assert main(["run", "--only", codes[1], "--study", str(study)]) == 0
    assert f"1 of the runs asked for have already finished ({codes[1]})" in capsys.readouterr().out
    assert len(rows(study)) == 2


def test_partial_files_and_logs_without_a_row_are_redone(study):
    code = plan(study)[0]["run_code"]
    runs = study / "runs"
    runs.mkdir()
    (runs / f".{code}.mcap.partial").write_bytes(b"half a log")
    (runs / f"{code}.mcap").write_bytes(b"a log whose row was never written")
    assert main(["run", "--only", code, "--study", str(study)]) == 0
    assert not (runs / f".{code}.mcap.partial").exists()
    assert FoxgloveReader(runs / f"{code}.mcap").metadata["run"]["run_code"] == code
    assert [r["run_code"] for r in rows(study)] == [code]


def test_lidar_perception_runs_the_tracker(study):
    code = next(r["run_code"] for r in plan(study) if r["Controller"] == "NaviGAN-R")
    assert main(["run", "--only", code, "--perception", "lidar", "--study", str(study)]) == 0
    (row,) = rows(study)
    assert row["perception"] == "lidar"
    log = FoxgloveReader(study / "runs" / f"{code}.mcap")
    seen = [m.data["ids"] for m in log.messages(["/perception/pedestrians"])]
    assert any(seen) and "noise_std_m" not in log.metadata["run"]


def one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    return lines[0]


def assert_nothing_ran(study: Path) -> None:
    assert not list(study.glob("runs/*.mcap")) and not (study / "outcomes.csv").exists()


def edit_plan(study: Path, line: int, column: str, value: str) -> None:
    table = plan(study)
    table[line - 2][column] = value
    with (study / "plan.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(table[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(table)


@pytest.mark.parametrize("change,args,message", [
    ("empty", [], "no plan in"),
    ("direction", [], "plan.csv line 4 (run"),
    ("controller", [], "Controller is 'Teleop', but the design has"),
    (None, ["--weights", "/nonexistent/weights.pt"], "no checkpoint at /nonexistent/weights.pt"),
    ("corrupt", [], "is not a readable checkpoint"),
    (None, ["--blind"], "--blind: the study in"),
    (None, ["--only", "ZZZZZ"], "run ZZZZZ is not in"),
    (None, ["--rerun", "first"], "the run has not finished yet"),
    (None, ["--workers", "0"], "argument --workers: expected a whole number from 1 to 256, got '0'"),
    (None, ["--dropout", "1.5"], "argument --dropout: expected a finite number in [0, 1), got '1.5'"),
    (None, ["--perception", "radar"], "argument --perception: invalid choice"),
    ("blind columns", [], "not those of an open study"),
])
def test_bad_input_is_one_line_exit_2_and_runs_nothing(study, tmp_path, capsys, change, args, message):
    if change == "empty":
        study = tmp_path / "empty"
        study.mkdir()
    elif change == "direction":
        edit_plan(study, 4, "Direction", "Diagonal")
    elif change == "controller":
        edit_plan(study, 2, "Controller", "Teleop")
    elif change == "corrupt":
        (tmp_path / "bad.pt").write_bytes(b"\x00 not torch")
        args = ["--weights", str(tmp_path / "bad.pt")]
    elif change == "blind columns":
        (study / "outcomes.csv").write_text(",".join(columns(blind=True)) + "\n")
    args = [a.replace("first", plan(study)[0]["run_code"]) if study.joinpath("plan.csv").exists() else a for a in args]
    assert main(["run", "--study", str(study), *args]) == 2
    assert message in one_error_line(capsys)
    if change != "blind columns":
        assert_nothing_ran(study)


def test_a_second_trials_run_on_the_same_study_is_refused(study, capsys):
    (study / "runs").mkdir()
    with (study / "runs" / ".lock").open("a+") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert main(["run", "--study", str(study)]) == 2
    assert "another `trials run` is running on" in one_error_line(capsys)
    assert_nothing_ran(study)


def test_log_show_of_a_run_without_a_log_is_one_line(finished, capsys):
    study, _ = finished
    assert main(["log", "show", "ZZZZZ", "--study", str(study)]) == 2
    assert "no log of run ZZZZZ in" in one_error_line(capsys)
    (study / "runs" / "broken.mcap").write_bytes(b"\x89MCAP0\r\n truncated")
    assert main(["log", "show", str(study / "runs" / "broken.mcap")]) == 2
    assert "is damaged or unfinished" in one_error_line(capsys)
    (study / "runs" / "broken.mcap").unlink()


def test_simulated_participants_judge_every_finished_run(finished):
    study, _ = finished
    with (study / "responses.csv").open(newline="") as handle:
        responses = list(csv.DictReader(handle))
    outcome = {r["run_code"]: r for r in rows(study)}
    assert {r["run_code"] for r in responses} == set(outcome)
    assert {r["source"] for r in responses} == {"simulated"}
    assert {r["compliant"] for r in responses} <= {"yes", "no"}
    for response in responses:  # seeded by the run's own seed, timed as the run's outcome
        assert response["seed"] == outcome[response["run_code"]]["seed"]
        assert response["recorded_utc"] == outcome[response["run_code"]]["finished_utc"]
    per_run = {code: sum(r["run_code"] == code for r in responses) for code in outcome}
    peds = {r["run_code"]: int(r["Pedestrians"]) for r in plan(study)}
    assert per_run == peds  # one participant per pedestrian by default


def test_no_responses_leaves_responses_csv_alone(study):
    code = plan(study)[0]["run_code"]
    assert main(["run", "--only", code, "--no-responses", "--study", str(study)]) == 0
    assert not (study / "responses.csv").exists()
