"""The conventions every `trials` command shares (issue 26a): --version, `trials status`, the run lock, the
[run] settings recorded per run, seeds a spreadsheet keeps, the progress convention and --json, console
run lines, --study, and usage errors that point to the command's own --help."""

from __future__ import annotations

import csv
import fcntl
import gc
import json
import os
import shutil
import sys
from importlib.metadata import entry_points, version
from pathlib import Path

import pytest

from robot_logs.run_log import read_run
from tests.support.run_studies import design_small_study
from trials import cli, progress
from trials.cli import main
from trials.commands.run import run_line
from trials.outcomes import columns, read_outcomes
from trials.run_events import RunEvent, append_run_event
from trials.run_settings import RunSettings, differences, read_run_settings, setting_names
from trials.runner import SEED_BITS, run_seed
from trials.study import StudyFolder


def rows(study: Path) -> list[dict[str, str]]:
    with (study / "outcomes.csv").open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def plan_codes(study: Path) -> list[str]:
    return [row["run_code"] for row in StudyFolder(study).read_plan()]


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("conventions") / "study"
    design_small_study(folder, blind=False)
    return folder


@pytest.fixture
def study(template, tmp_path) -> Path:
    return Path(shutil.copytree(template, tmp_path / "study"))


# --- --version and usage errors ------------------------------------------------------------------

def test_version_prints_the_installed_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"trials (navtrials) {version('navtrials')}"


def test_the_trials_script_exits_with_mains_code_and_skips_the_last_collection(monkeypatch):
    """The installed script runs `console`, which exits with `main`'s code after freezing what is left for the exit
    to free, rather than collecting it."""
    (script,) = [entry for entry in entry_points(group="console_scripts") if entry.name == "trials"]
    assert script.value == "trials.cli:console"
    monkeypatch.setattr(cli, "main", lambda: 3)
    try:
        with pytest.raises(SystemExit) as exit_:
            cli.console()
        assert exit_.value.code == 3 and gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()


@pytest.mark.parametrize("argv, command", [(["run", "--bogus"], "trials run"), (["status", "extra"], "trials status"),
                                           (["log", "show", "X", "--bogus"], "trials log show"), (["--bogus"], "trials")])
def test_usage_errors_point_to_the_typed_commands_help(argv, command, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.endswith(f"(see `{command} --help`)\n"), err


# --- seeds ---------------------------------------------------------------------------------------

def test_run_seeds_are_exact_as_doubles_and_differ_by_run():
    seeds = [run_seed(study_seed, code) for study_seed in (0, 11, 2**31 - 1) for code in ("AAAAA", "PE7Y9", "ZZZZZ")]
    assert all(0 <= s < 2**SEED_BITS and int(float(s)) == s for s in seeds)
    assert len(set(seeds)) == len(seeds)
    assert max(seeds) > 2**50  # the whole 53-bit range is used, not a few bits of it


# --- the [run] settings --------------------------------------------------------------------------

def test_run_table_is_read_and_checked(tmp_path):
    spec = tmp_path / "study.toml"
    assert read_run_settings(spec) == RunSettings()  # no file: the defaults
    spec.write_text('[study]\nname = "x"\n\n[run]\nperception = "lidar"\nnoise = 0.2\ntimeout = 30\nweights = "mine.pt"\n')
    settings = read_run_settings(spec)
    assert settings == RunSettings("lidar", 0.2, 0.05, 30.0, "mine.pt")
    assert settings.recorded() == {"perception": "lidar", "noise_std_m": "0.200", "dropout": "0.050",
                                   "timeout_s": "30.000", "weights": "mine.pt"}
    assert tuple(settings.recorded()) == setting_names()


def test_relative_weights_in_the_run_table_are_the_studys_own(tmp_path):
    spec = tmp_path / "study.toml"
    spec.write_text('[run]\nweights = "mine.pt"\n')
    assert read_run_settings(spec).weights == "mine.pt"  # no such file beside it: a shipped name, as written
    (tmp_path / "mine.pt").write_bytes(b"weights")
    assert read_run_settings(spec).weights == str(tmp_path / "mine.pt")


def test_differences_name_each_changed_setting_and_skip_unrecorded_and_logged_runs():
    recorded = RunSettings().recorded()
    assert differences(recorded, RunSettings(noise_std_m=0.3)) == ["noise_std_m 0.050 -> 0.300"]
    assert differences(recorded, RunSettings()) == []
    assert differences({name: "" for name in recorded} | {"perception": "positions"}, RunSettings(noise_std_m=0.3)) == []
    assert differences({**recorded, "perception": "log"}, RunSettings(timeout_s=5.0)) == []


def test_outcomes_written_before_the_settings_columns_still_read(tmp_path):
    old = columns(blind=False, settings=False)
    assert old == columns(blind=False)[:len(old)] and len(columns(blind=False)) - len(old) == 4
    path = tmp_path / "outcomes.csv"
    cells = {"run_code": "AAAAA", "status": "goal", "seed": str(2**62 + 7), "perception": "positions", "controller": "Lattice",
             "finished_utc": "2026-05-01T10:00:00+00:00", "collisions": "0", "time_to_goal_s": "10.0"}
    path.write_text(",".join(old) + "\n" + ",".join(cells.get(c, "1.5") for c in old) + "\n")
    (outcome,) = read_outcomes(path, blind=False)
    assert outcome.seed == 2**62 + 7 and outcome.noise_std_m is None and outcome.weights is None


# --- console lines and the progress convention ---------------------------------------------------

def test_a_run_line_names_order_code_settings_outcome_and_the_gap():
    plan_row = {"order": "3", "run_code": "PE7Y9", "Pedestrians": "2", "Controller": "A"}
    outcome = {"status": "goal", "duration_s": "10.700", "min_distance_m": "1.429"}
    assert run_line(plan_row, outcome) == (
        "order 3, PE7Y9 (Pedestrians 2, Controller A): goal after 10.7 s; smallest gap robot footprint to pedestrian 1.43 m")
    assert run_line(plan_row, {**outcome, "min_distance_m": ""}).endswith("goal after 10.7 s; no pedestrian")


def test_piped_progress_numbers_each_line_and_shows_no_bar_or_startup_line(capsys):
    bar = progress.Progress("run", "running")
    bar.loading("Loading the controllers")
    bar.start(2)
    bar.item("first")
    bar.item("second", error=True)
    bar.close()
    captured = capsys.readouterr()
    assert captured.out == "[1/2] first\n" and captured.err == "[2/2] second\n"


class _Writes:
    """A stream that keeps each write apart, to count the writes a reader could time."""

    def __init__(self) -> None:
        self.writes: list[str] = []

    def write(self, text: str) -> int:
        self.writes.append(text)
        return len(text)

    def flush(self) -> None:
        pass


def test_held_lines_come_in_one_write_per_stream_in_the_order_given(monkeypatch):
    out, err = _Writes(), _Writes()
    monkeypatch.setattr(sys, "stdout", out)
    monkeypatch.setattr(sys, "stderr", err)
    bar = progress.Progress("run", "running", bar=False)
    bar.start(5)
    bar.close()
    bar.held([("a", False), ("b", False), ("c", True), ("d", False), ("e", False)])
    assert out.writes == ["[1/5] a\n[2/5] b\n", "[4/5] d\n[5/5] e\n"] and err.writes == ["[3/5] c\n"]
    assert bar.count == 5


def test_quiet_progress_prints_nothing(capsys):
    bar = progress.Progress("run", "running", quiet=True)
    bar.loading("Loading")
    bar.start(2)
    bar.item("first")
    bar.held([("second", False)])
    assert capsys.readouterr() == ("", "") and bar.count == 2


def test_on_a_terminal_the_startup_line_and_a_bar_show(monkeypatch, capsys):
    monkeypatch.setattr(progress, "on_terminal", lambda stream=None: True)
    bar = progress.Progress("run", "running")
    bar.loading("Loading the controllers")
    bar.start(1)
    bar.item("first")
    bar.close()
    captured = capsys.readouterr()
    assert captured.err.startswith("Loading the controllers...\n") and "1/1" in captured.err
    assert captured.out == "[1/1] first\n"


# --- trials status ------------------------------------------------------------------------------

def test_status_of_a_new_study_counts_the_plan_per_controller(study, capsys):
    assert main(["status", "--study", str(study)]) == 0
    text = capsys.readouterr().out
    assert "small-open (open study)" in text and "runs: 0 of 6 finished" in text
    assert "controller Lattice: 3 planned" in text and "controller NaviGAN-R: 3 planned" in text
    assert "report: none yet" in text and "unblinded" not in text and "lock:" not in text


def test_status_tells_failed_aborted_stale_and_held(study, capsys):
    folder = StudyFolder(study)
    first, second, third = plan_codes(study)[:3]
    (study / "runs").mkdir()
    folder.run_failure(first).write_text("the controller could not be built\n")
    folder.run_log(second).with_name(f".{second}.mcap.partial").write_bytes(b"half")
    (study / "runs" / ".lock").write_text("4242")
    assert main(["status", "--study", str(study), "--json"]) == 0
    status = json.loads(capsys.readouterr().out)
    assert status["failed"] == {first: "the controller could not be built"} and status["aborted"] == [second]
    assert status["lock"] == {"held": False, "stale": True, "pid": "4242"}
    assert sum(a["failed"] for a in status["arms"].values()) == 1 and sum(a["pending"] for a in status["arms"].values()) == 4
    with (study / "runs" / ".lock").open("a+") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert main(["status", "--study", str(study)]) == 0
    text = capsys.readouterr().out
    assert "a `trials run` is running on the study (pid 4242)" in text and "1 running" in text
    assert third not in text


def test_status_counts_the_field_days_started_and_aborted_runs(study, capsys):
    """What the console records (`run_events.csv`) shows in `trials status` before any log is played."""
    folder = StudyFolder(study)
    first, second = plan_codes(study)[:2]
    for code, event, detail in ((first, "start", ""), (second, "start", ""), (second, "abort", "a visitor crossed the course")):
        append_run_event(folder, RunEvent(code, event, detail, "2026-12-02T09:00:00+00:00"))
    assert main(["status", "--study", str(study), "--json"]) == 0
    status = json.loads(capsys.readouterr().out)
    assert status["aborted"] == [second]
    assert sum(a["running"] for a in status["arms"].values()) == 1 and sum(a["pending"] for a in status["arms"].values()) == 4


def test_status_of_a_blinded_study_counts_arm_labels_without_opening_the_key(tmp_path, monkeypatch, capsys):
    study = tmp_path / "blind"
    design_small_study(study, blind=True)
    capsys.readouterr()

    def refuse(*args, **kwargs):
        raise AssertionError("trials status opened the sealed key")

    monkeypatch.setattr(StudyFolder, "open_sealed", refuse)
    monkeypatch.setattr(StudyFolder, "read_sealed", refuse)
    assert main(["status", "--study", str(study)]) == 0
    text = capsys.readouterr().out
    assert "arm A: 3 planned" in text and "arm B: 3 planned" in text and "unblinded: no (the sealed key is closed)" in text
    assert "NaviGAN" not in text and "Lattice" not in text


# --- runs end to end -----------------------------------------------------------------------------

@pytest.mark.slow
def test_run_records_its_settings_refuses_a_mix_and_the_report_flags_it(study, capsys):
    first, second = plan_codes(study)[:2]
    spec = study / "study.toml"
    spec.write_text(spec.read_text() + "\n[run]\nnoise = 0.1\ntimeout = 30\n")
    (study / "runs").mkdir()
    (study / "runs" / ".lock").write_text("999999")  # left by a killed run
    assert main(["run", "--study", str(study), "--only", first, "--no-responses"]) == 0
    captured = capsys.readouterr()
    assert "runs/.lock was left by pid 999999" in captured.err
    assert captured.out.startswith("[1/1] order 1, ") and not (study / "runs" / ".lock").exists()
    (row,) = rows(study)
    assert (row["noise_std_m"], row["dropout"], row["timeout_s"], row["weights"]) == ("0.100", "0.050", "30.000", "shipped")
    assert int(row["seed"]) == run_seed(11, first) < 2**53
    meta = read_run(StudyFolder(study).run_log(first)).metadata
    assert (meta["noise_std_m"], meta["timeout_s"], meta["weights"], meta["seed"]) == ("0.1", "30", "shipped", row["seed"])

    assert main(["run", "--study", str(study), "--only", second, "--noise", "0.3"]) == 2
    err = capsys.readouterr().err
    assert f"run {first} ran with other settings (noise_std_m 0.100 -> 0.300)" in err and "--settings-differ" in err
    assert len(rows(study)) == 1

    assert main(["run", "--study", str(study), "--only", second, "--noise", "0.3", "--settings-differ", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert [r["run_code"] for r in printed["finished"]] == [second] and printed["finished"][0]["noise_std_m"] == "0.300"
    assert main(["status", "--study", str(study)]) == 0
    assert "finished runs were made with different settings" in capsys.readouterr().out
    assert main(["report", "--study", str(study), "--quiet"]) == 0
    report = (study / "report" / "report.md").read_text()
    assert "The runs were not all made with the same settings (1 with perception positions, noise_std_m 0.100" in report
    assert "1 with perception positions, noise_std_m 0.300" in report
    assert main(["status", "--study", str(study)]) == 0
    assert "report: up to date with the data" in capsys.readouterr().out
    later = (study / "report" / "report.json").stat().st_mtime + 60
    os.utime(study / "outcomes.csv", (later, later))  # a newer time alone changes nothing: freshness is by content
    assert main(["status", "--study", str(study)]) == 0
    assert "report: up to date with the data" in capsys.readouterr().out
    assert main(["score", second, "2", "--by", "E1", "--study", str(study)]) == 0
    assert main(["status", "--study", str(study)]) == 0
    assert "report: older than the data: run `trials report` again" in capsys.readouterr().out


@pytest.mark.slow
def test_an_old_study_reruns_with_its_recorded_63_bit_seed_and_reproduces(study, capsys):
    first = plan_codes(study)[0]
    assert main(["run", "--study", str(study), "--only", first, "--no-responses", "--quiet"]) == 0
    (new,) = rows(study)
    # Rewrite the row as an earlier release did: no settings columns, a 63-bit seed.
    old_seed = 2**62 + 12345
    old = columns(blind=False, settings=False)
    with (study / "outcomes.csv").open("w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(old)
        writer.writerow([str(old_seed) if c == "seed" else new[c] for c in old])
    assert main(["run", "--study", str(study), "--rerun", first, "--no-responses", "--quiet"]) == 0
    (once,) = rows(study)
    assert list(once) == list(columns(blind=False)) and int(once["seed"]) == old_seed
    assert main(["run", "--study", str(study), "--rerun", first, "--no-responses", "--quiet"]) == 0
    (twice,) = rows(study)
    metrics = [c for c in columns(blind=False) if c.endswith(("_s", "_m", "_mps2", "_mps3", "_rad_per_m"))]
    assert [twice[c] for c in metrics] == [once[c] for c in metrics] and twice["seed"] == once["seed"]
    assert main(["status", "--study", str(study)]) == 0
    assert "runs: 1 of 6 finished" in capsys.readouterr().out


@pytest.mark.slow
def test_log_inspect_takes_a_run_code_and_prints_json(study, capsys):
    first = plan_codes(study)[0]
    assert main(["run", "--study", str(study), "--only", first, "--no-responses", "--quiet"]) == 0
    capsys.readouterr()
    assert main(["log", "inspect", first, "--study", str(study), "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["path"].endswith(f"runs/{first}.mcap") and record["format"] == "MCAP file"
    assert {"/robot/state", "/events"} <= {t["name"] for t in record["topics"]}
    assert record["record_span_s"] > 0


# --- --study on the commands outside the study workflow ------------------------------------------

def test_evaluate_writes_into_the_study_folder(tmp_path, capsys):
    assert main(["evaluate", "--baseline", "constant-velocity", "--split", "eth", "--study", str(tmp_path), "--quiet"]) == 0
    result = json.loads((tmp_path / "constant-velocity-eth-eval.json").read_text())
    assert result["split"] == "eth" and result["full"]["ade"] > 0
    assert f"wrote {tmp_path / 'constant-velocity-eth-eval.json'}" in capsys.readouterr().out


def test_json_of_design_holds_the_record_it_wrote(tmp_path, capsys):
    folder = tmp_path / "ab"
    assert main(["design", "--ab", "--study", str(folder), "--json", "--seed", "5"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["design"] == json.loads((folder / "design.json").read_text())
    assert printed["commitment"] == printed["design"]["blinding"]["commitment"]["digest"]
    assert printed["design"]["seed"] == 5 and Path(printed["files"][0]).parent == folder


def test_playback_goes_into_the_study_folder_and_prints_json(eth_ucy_dir, tmp_path, capsys):
    assert main(["playback", "--data", str(eth_ucy_dir), "--study", str(tmp_path), "--split", "zara1", "--models", "human",
                 "--episodes", "3", "--json", "--quiet"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["out"] == str(tmp_path / "playback") and (tmp_path / "playback" / "table1.md").exists()
    pooled = printed["tables"][0]
    assert pooled["values"]["human"]["episodes"] == 3 and 0 <= pooled["values"]["human"]["A"] <= 1
    assert {t["scope"] for t in printed["tables"][2:]} == {"zara1"}


def test_piped_playback_prints_a_numbered_line_per_column_walked(eth_ucy_dir, tmp_path, capsys):
    assert main(["playback", "--data", str(eth_ucy_dir), "--out", str(tmp_path / "pb"), "--split", "zara1",
                 "--models", "human,navigan-r", "--episodes", "2"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("[")]
    assert [line.split(":")[0] for line in lines] == ["[1/2] zara1 R", "[2/2] zara1 human"]
