"""The field day end to end in real browsers (Debian's Chromium through Selenium): `trials serve` on a
blinded study, two runs worked through by the experimenter with the sample bag attached (uploaded, then
by path), scored, and judged by three participants from their own browsers; then `trials report
--unblind` with no other command in between. The files left are those the command line leaves."""

from __future__ import annotations

import csv
import gzip
import json
import shutil
from pathlib import Path

import pytest

from tests.support.blinding import NAMES
from tests.support.console import WINDOW, chromium_ready, design_study, field_day, served
from trials.cli import main

pytestmark = [pytest.mark.slow, pytest.mark.skipif(not chromium_ready(), reason="no chromium and chromium-driver (apt-get install chromium chromium-driver)")]


def rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def day(tmp_path_factory, robot_logs_dir):
    """The study after its field day in the console, and a copy of the same design run by `trials run --from-log`."""
    root = tmp_path_factory.mktemp("field-day")
    study = design_study(root / "study")
    by_command = root / "by-command"
    shutil.copytree(study, by_command)
    log = robot_logs_dir / "stationary_ros1.bag"
    with served(study) as url:
        pages = field_day(url, study, log)
    assert main(["run", "--study", str(by_command), "--from-log", str(log), "--start", WINDOW["start"], "--duration", WINDOW["duration"]]) == 0
    return study, by_command, pages, log


def test_no_page_the_console_showed_named_a_controller(day):
    _, _, pages, _ = day
    assert len(pages) > 15
    named = [page.splitlines()[0] for page in pages if NAMES.search(page.encode())]
    assert named == []


def test_the_runs_are_the_ones_trials_run_from_log_makes(day):
    study, by_command, _, log = day
    console, command = rows(study / "outcomes.csv"), rows(by_command / "outcomes.csv")
    assert [r["run_code"] for r in console] == [r["run_code"] for r in command]
    for mine, theirs in zip(console, command):
        assert {k: v for k, v in mine.items() if k != "finished_utc"} == {k: v for k, v in theirs.items() if k != "finished_utc"}
        assert mine["perception"] == "log" and "controller" not in mine
    for row in console:
        code = row["run_code"]
        assert (study / "runs" / f"{code}.mcap").stat().st_size > 10_000
        sealed = json.loads(gzip.decompress((study / "sealed" / "runs" / f"{code}.json.gz").read_bytes()))
        assert sealed["run_code"] == code and sealed["topics"]["/controller/plan"]
    first = console[0]["run_code"]
    assert (study / "logs" / f"{first}.bag").read_bytes() == log.read_bytes()  # the upload, kept in the study


def test_the_experimenter_the_evaluator_and_three_participants_are_recorded(day):
    study, _, _, log = day
    codes = [r["run_code"] for r in rows(study / "plan.csv")]
    events = [(e["run_code"], e["event"]) for e in rows(study / "run_events.csv")]
    assert events == [(c, e) for c in codes for e in ("start", "note", "finish", "log")]
    details = [e["detail"] for e in rows(study / "run_events.csv") if e["event"] == "log"]
    assert details == [f"logs/{codes[0]}.bag", str(log)]
    assert [(s["run_code"], s["score"], s["scorer"]) for s in rows(study / "scores.csv")] == [(codes[0], "3", "evaluator-1"), (codes[1], "2", "evaluator-1")]
    answers = [(r["run_code"], r["participant"], r["compliant"], r["source"], r["comfort"]) for r in rows(study / "responses.csv")]
    assert sorted(answers) == sorted([(codes[0], "P01", "yes", "human", "4"), (codes[1], "P01", "no", "human", "4"),
                                      (codes[0], "P02", "yes", "human", "4"), (codes[1], "P02", "no", "human", "4"),
                                      (codes[0], "P03", "no", "human", "4"), (codes[1], "P03", "no", "human", "4")])


def test_the_study_reports_and_unblinds_with_no_command_in_between(day):
    study, _, _, _ = day
    assert main(["report", "--study", str(study), "--unblind"]) == 0
    arms = json.loads((study / "sealed" / "allocation.json").read_text())["arms"]
    first_arm = arms[rows(study / "plan.csv")[0]["Controller"]]  # the run P01 and P02 judged compliant, P03 not
    second_arm = next(level for level in arms.values() if level != first_arm)
    [line] = rows(study / "report" / "tables" / "a_b_comparison_table_ii.csv")
    assert (line[f"{first_arm}: runs"], line[f"{first_arm}: yes / judged"]) == ("1", "2 / 3")
    assert (line[f"{second_arm}: runs"], line[f"{second_arm}: yes / judged"]) == ("1", "0 / 3")
    assert json.loads((study / "report" / "unblinding.json").read_text())["unblinded_utc"]
