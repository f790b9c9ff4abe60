"""A blinded study runs blind: no public file, log, metadata or console line names a controller."""

from __future__ import annotations

import csv
import gzip
import json
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from robot_logs.foxglove_log import FoxgloveReader
from robot_logs.run_log import CONTROLLER_TOPICS
from tests.support.blinding import NAMES, mcap_text
from tests.support.registration import recorded_digest
from tests.support.run_studies import design_small_study
from trials.cli import main
from trials.sealed_runs import SEALED_BLOCK

pytestmark = pytest.mark.slow  # a blinded study run end to end in worker processes


def trials(*args: str) -> subprocess.CompletedProcess:
    """The real command in its own process, workers included: everything it prints is captured."""
    return subprocess.run([sys.executable, "-m", "trials.cli", *args], capture_output=True, timeout=300)


@pytest.fixture(scope="module")
def blind_run(tmp_path_factory):
    study = tmp_path_factory.mktemp("blind") / "study"
    design_small_study(study, blind=True)
    run = trials("run", "--blind", "--workers", "2", "--study", str(study), "--wall-clock")
    one_per_arm = {row["Controller"]: row["run_code"] for row in _plan(study)}
    shows = [trials("log", "show", code, "--study", str(study)) for code in one_per_arm.values()]
    rerun = trials("run", "--rerun", *reversed(one_per_arm.values()), "--workers", "2", "--json", "--wall-clock", "--study", str(study))
    return study, [run, *shows, rerun, trials("status", "--study", str(study)), trials("status", "--json", "--study", str(study))]


def _plan(study: Path) -> list[dict[str, str]]:
    with (study / "plan.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_the_blind_run_finishes_every_row(blind_run):
    study, (run, *shows) = blind_run
    assert run.returncode == 0, run.stderr.decode()
    assert b"6 runs finished" in run.stdout
    with (study / "outcomes.csv").open(newline="") as handle:
        table = list(csv.DictReader(handle))
    # In plan order, though two workers finished them in their own order (which would time the controllers); the
    # reruns' rows go back to their places too.
    assert [r["run_code"] for r in table] == [r["run_code"] for r in _plan(study)]
    with (study / "responses.csv").open(newline="") as handle:
        judged = list(dict.fromkeys(r["run_code"] for r in csv.DictReader(handle)))
    assert judged == [r["run_code"] for r in _plan(study) if r["run_code"] in judged] and len(judged) >= 4
    assert "controller" not in table[0]
    assert all(show.returncode == 0 for show in shows)


def test_status_counts_by_arm_label_and_the_run_lines_are_numbered(blind_run):
    study, (run, *_, rerun, status, as_json) = blind_run
    assert status.returncode == 0, status.stderr.decode()
    text = status.stdout.decode()
    assert "small-ab (blinded study)" in text and "runs: 6 of 6 finished" in text
    assert "arm A: 3 planned" in text and "arm B: 3 planned" in text and "unblinded: no" in text
    arms = json.loads(as_json.stdout)["arms"]
    assert sorted(arms) == ["A", "B"] and all(sum(a["finished"].values()) == 3 and a["pending"] == 0 for a in arms.values())
    numbered = [line for line in run.stdout.decode().splitlines() if line.startswith("[")]
    assert [line.split("]")[0] for line in numbered] == [f"[{n}/6" for n in range(1, 7)]
    assert all(", Controller A," in line or ", Controller B," in line for line in numbered)
    assert not (study / "runs" / ".lock").exists()
    printed = json.loads(rerun.stdout)  # in plan order, whichever ended first, and with no controller column
    plan = [row["run_code"] for row in _plan(study)]
    codes = [row["run_code"] for row in printed["finished"]]
    assert len(codes) == 2 and codes == sorted(codes, key=plan.index)
    assert all("controller" not in row for row in printed["finished"])


def test_nothing_public_names_a_controller(blind_run):
    study, processes = blind_run
    for process in processes:
        assert not NAMES.search(process.stdout) and not NAMES.search(process.stderr), process.stdout + process.stderr
    checked = 0
    for path in study.rglob("*"):
        if path.is_dir() or "sealed" in path.relative_to(study).parts:
            continue
        content = mcap_text(path) if path.suffix == ".mcap" else path.read_bytes()
        assert not NAMES.search(content), f"{path} names a controller"
        assert not NAMES.search(path.name.encode())
        checked += 1
    assert checked >= 6 + 2 + 5  # logs, pictures, and the study's own files were all read


def test_the_sealed_part_holds_the_controller_output(blind_run):
    study, _ = blind_run
    arms = json.loads((study / "sealed" / "allocation.json").read_text())["arms"]
    for row in _plan(study):
        path = study / "sealed" / "runs" / f"{row['run_code']}.json.gz"
        assert path.stat().st_size == SEALED_BLOCK and stat.S_IMODE(path.stat().st_mode) == 0o600
        record = json.loads(gzip.decompress(path.read_bytes()))
        assert record["arm"] == row["Controller"] and record["controller"] == arms[row["Controller"]]
        steps, plans = record["topics"]["/controller/record"], record["topics"]["/controller/plan"]
        assert steps and all("record" in step and "t" in step for step in steps)
        assert [p["t"] for p in plans] == [s["t"] for s in steps] and all(p["waypoints"] for p in plans)
        assert NAMES.search(json.dumps(record).encode())
    assert stat.S_IMODE((study / "sealed").stat().st_mode) == 0o700
    assert stat.S_IMODE((study / "sealed" / "runs").stat().st_mode) == 0o700


def test_a_log_of_a_blind_run_has_no_controller_output(blind_run):
    study, _ = blind_run
    for row in _plan(study):
        content = mcap_text(study / "runs" / f"{row['run_code']}.mcap")
        for topic in CONTROLLER_TOPICS:
            assert topic.name.encode() not in content and topic.schema.encode() not in content


def test_wall_clock_stamps_of_a_blind_run_are_whole_minutes(blind_run):
    study, _ = blind_run
    for row in _plan(study):
        log = FoxgloveReader(study / "runs" / f"{row['run_code']}.mcap")
        start = int(log.metadata["clock"]["start_ns"])
        assert start > 0 and start % 60_000_000_000 == 0 and log.metadata["clock"]["start_utc"].endswith(":00+00:00")
        state = next(log.messages(["/robot/state"]))
        assert state.stamp_ns == start and state.data["t"] == 0.0


def test_a_broken_sealed_key_stops_the_run_before_it_starts(tmp_path, capsys):
    study = tmp_path / "study"
    design_small_study(study, blind=True)
    key = study / "sealed" / "allocation.json"
    data = json.loads(key.read_text())
    data["arms"] = {"A": data["arms"]["B"], "B": data["arms"]["A"]}
    key.write_text(json.dumps(data))
    assert main(["run", "--study", str(study)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not match the commitment in design.json" in err[0]
    assert not NAMES.search(err[0].encode())
    key.unlink()
    assert main(["run", "--study", str(study)]) == 2
    assert f"error: the sealed key {key} is missing" in capsys.readouterr().err
    assert not list(study.glob("runs/*.mcap")) and not (study / "outcomes.csv").exists()


def test_log_show_unblind_adds_the_sealed_controller_and_plans(blind_run, capsys):
    study, _ = blind_run
    key = json.loads((study / "sealed" / "allocation.json").read_text())["arms"]
    recorded = recorded_digest(study)
    row = _plan(study)[0]
    record = json.loads(gzip.decompress((study / "sealed" / "runs" / f"{row['run_code']}.json.gz").read_bytes()))
    assert main(["log", "show", row["run_code"], "--study", str(study), "--unblind", "--commitment", recorded]) == 0
    out = capsys.readouterr().out
    plans = len(record["topics"]["/controller/plan"])
    assert f"arm {row['Controller']} is {key[row['Controller']]}; controller: {key[row['Controller']]}" in out
    assert f"{plans} plans and {plans} controller records in" in out and "recorded outside the study" in out
    # Showing the key is an unblinding like the report's, recorded with the study's completeness.
    (opening,) = json.loads((study / "unblinding.json").read_text())["openings"]
    assert (opening["command"], opening["completeness"], opening["interim"]) == (f"trials log show {row['run_code']} --unblind",
                                                                                "6 of 6 runs finished", None)
    assert main(["status", "--study", str(study)]) == 0
    assert f"unblinded: yes, on {opening['utc']}" in capsys.readouterr().out
    assert main(["log", "show", row["run_code"], "--study", str(study), "--commitment", recorded]) == 2
    assert "give them with --unblind" in capsys.readouterr().err
    assert main(["log", "show", row["run_code"], "--study", str(study), "--unblind"]) == 2
    assert "--unblind needs --commitment HEX" in capsys.readouterr().err
