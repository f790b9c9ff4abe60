"""Interrupting `trials run` (a kill, or Ctrl-C) loses and duplicates nothing; the next run continues."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robot_logs.foxglove_log import FoxgloveReader
from trials.cli import main
from trials.runner import clean_partials
from trials.study import StudyFolder

pytestmark = pytest.mark.slow  # runs killed and resumed in their own processes

RUNS = 12


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("resume") / "study"
    assert main(["design", "--runs", str(RUNS), "--seed", "3", "--study", str(folder)]) == 0
    return folder


@pytest.fixture
def study(template, tmp_path) -> Path:
    import shutil

    return Path(shutil.copytree(template, tmp_path / "study"))


def finished_rows(study: Path) -> list[dict[str, str]]:
    path = study / "outcomes.csv"
    if not path.exists():
        return []
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def _default_interrupt() -> None:
    """Ctrl-C as at a terminal: a test run started in the background inherits SIGINT ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(study: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "trials.cli", "run", "--workers", "2", "--study", str(study)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=_default_interrupt)


def wait_for_rows(study: Path, process: subprocess.Popen, count: int) -> None:
    deadline = time.monotonic() + 120
    while len(finished_rows(study)) < count:
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "no runs finished in time"
        time.sleep(0.05)


def listing(study: Path) -> dict[str, int]:
    return {str(p.relative_to(study)): p.stat().st_size for p in study.rglob("*") if p.is_file()}


def check_complete(study: Path, before: list[dict[str, str]]) -> None:
    rows = finished_rows(study)
    codes = [r["run_code"] for r in rows]
    with (study / "plan.csv").open(newline="") as handle:
        planned = [r["run_code"] for r in csv.DictReader(handle)]
    assert sorted(codes) == sorted(planned) and len(set(codes)) == RUNS  # every run exactly once
    kept = {r["run_code"] for r in before}
    assert [r for r in rows if r["run_code"] in kept] == before  # the rows written before the interruption are untouched
    assert codes == [c for c in planned if c in set(codes)]  # in plan order, whatever order the runs ended in
    for code in planned:
        assert FoxgloveReader(study / "runs" / f"{code}.mcap").metadata["run"]["run_code"] == code
    assert not [p for p in study.rglob(".*") if p.name.endswith((".partial", ".tmp"))]
    # Every finished run has its simulated judgments, exactly once, seeded by its seed, in plan order.
    with (study / "responses.csv").open(newline="", encoding="utf-8") as handle:
        judgments = list(csv.DictReader(handle))
    judged = list(dict.fromkeys(j["run_code"] for j in judgments))
    assert judged == planned
    assert len({(j["run_code"], j["participant"]) for j in judgments}) == len(judgments)
    seeds = {r["run_code"]: r["seed"] for r in rows}
    assert all(j["source"] == "simulated" and j["seed"] == seeds[j["run_code"]] for j in judgments)


def test_a_killed_run_loses_and_duplicates_nothing(study):
    process = start(study)
    wait_for_rows(study, process, 3)
    process.kill()  # SIGKILL: no clean-up of any kind in the parent
    process.wait()
    before = finished_rows(study)
    assert 3 <= len(before) < RUNS
    snapshot = listing(study)
    time.sleep(1.5)
    assert listing(study) == snapshot  # its workers died with it: nothing more is written
    resumed = subprocess.run([sys.executable, "-m", "trials.cli", "run", "--workers", "2", "--study", str(study)], capture_output=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr.decode()
    assert f"{RUNS - len(before)} runs finished".encode() in resumed.stdout
    check_complete(study, before)


def test_ctrl_c_stops_at_once_and_the_next_run_continues(study):
    process = start(study)
    wait_for_rows(study, process, 2)
    os.killpg(process.pid, signal.SIGINT)  # what the terminal sends to the whole foreground group
    _, err = process.communicate(timeout=30)
    finished = len(finished_rows(study))
    assert process.returncode == 130, f"{finished} of {RUNS} runs finished: the interrupt did not stop the run"
    assert b"interrupted: finished work is kept; run the command again to continue" in err
    assert b"Traceback" not in err
    before = finished_rows(study)
    assert not [p for p in study.rglob(".*") if p.name.endswith((".partial", ".tmp"))]  # cleaned on the way out
    assert main(["run", "--study", str(study)]) == 0
    check_complete(study, before)


def test_only_what_interrupted_runs_half_wrote_is_cleaned(tmp_path):
    (tmp_path / "runs").mkdir()
    (tmp_path / "sealed" / "runs").mkdir(parents=True)
    stale = [tmp_path / "runs" / ".6PKG7.mcap.partial", tmp_path / "sealed" / "runs" / ".6PKG7.json.a1b2c3d4.tmp",
             tmp_path / ".outcomes.csv.0f1e2d3c.tmp", tmp_path / ".responses.csv.fb6f1b67.tmp"]
    kept = [tmp_path / "runs" / "6PKG7.mcap", tmp_path / ".notes.tmp", tmp_path / "responses.csv"]
    for path in stale + kept:
        path.write_text("x")
    assert sorted(clean_partials(StudyFolder(tmp_path))) == sorted(stale)
    assert sorted(p for p in tmp_path.rglob("*") if p.is_file()) == sorted(kept)
