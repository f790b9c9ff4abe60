"""The field day end to end in real browsers (Debian's Chromium through Selenium): `trials serve` on a
blinded study, two runs worked through by the experimenter with the sample bag attached (uploaded, then
by path), scored, and judged by three participants from their own browsers; then `trials report
--unblind` with no other command in between. The files left are those the command line leaves.

And live runs on a real ROS 1 master with the software robot (`trials robot-sim`): Start drives a run to
its end while the page follows its state, and E-STOP stops one while it drives."""

from __future__ import annotations

import csv
import gzip
import json
import re
import shutil
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.support.blinding import NAMES
from tests.support.console import WINDOW, browser, chromium_ready, design_study, field_day, go, served
from tests.support.live_rig import Rig
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
    commitment = json.loads((study / "design.json").read_text())["blinding"]["commitment"]["digest"]  # as `trials design` printed it
    assert main(["report", "--study", str(study), "--unblind", "--commitment", commitment]) == 0
    arms = json.loads((study / "sealed" / "allocation.json").read_text())["arms"]
    plan = rows(study / "plan.csv")
    codes = [row["run_code"] for row in plan]
    record = json.loads((study / "report" / "report.json").read_text())
    assert [record["scores"][row["run_code"]]["arm"] for row in plan] == [arms[row["Controller"]] for row in plan]
    # Both logs were attached: the toolkit drove neither robot, so no judgment or score is credited to a controller.
    assert record["runs"]["made"] == {"simulated": 0, "driven live": 0, "external log": 2}
    assert record["runs"]["left_out_of_comparisons"] == codes and record["table_ii"] == [] and record["fits"] == []
    markdown = (study / "report" / "report.md").read_text()
    assert (f"2 runs ({codes[0]}, {codes[1]}) were played from an external robot log: the toolkit did not drive those robots, so their "
            "6 judgment(s) and 2 human score(s) are not credited to a controller") in markdown
    assert "No judgments of runs the toolkit drove yet" in markdown
    assert json.loads((study / "report" / "unblinding.json").read_text())["unblinded_utc"]


# --- live runs: a real ROS 1 master, the software robot, `trials run --robot` started from the console ---------------

#: Seconds a live run may take to reach a state here: starting Python, loading both controllers and reaching the
#: master take a while on a loaded 2-core machine; a run drives for about 10 s.
LIVE_DEADLINE_S = 300.0
ENDINGS = ("goal", "collision", "timeout")


@dataclass(frozen=True)
class Robot:
    """A blinded A/B study driven live on the software robot, the console serving it, and the rig (the robot and a witness of its commands)."""

    study: Path
    uri: str
    url: str
    rig: Rig


@pytest.fixture(scope="module")
def robot(tmp_path_factory) -> Iterator[Robot]:
    """`rosmaster` on a free port, `trials robot-sim` on it with a witness of its velocity commands, `trials design --ab
    --robot` and `trials serve`; every process is stopped however the tests end."""
    from tests.support.live_rig import live_rig, repository_env
    from tests.support.ros1_echo import environment
    from tests.support.ros1_master import master_process

    root = tmp_path_factory.mktemp("live")
    with master_process(root / "ros") as (uri, _):
        study = root / "study"
        assert main(["design", "--ab", "--robot", str(uri), "--study", str(study), "--quiet"]) == 0
        # A loaded machine delivers scans late now and then: a longer watchdog and sensor wait than a robot's keep
        # these runs from stopping for that (tests/test_robot_live_ros1.py tests the stop rules themselves).
        robot_table(study, watchdog="2.0", sensor_wait="60.0")
        env = {**repository_env(), **environment(root / "ros")}
        with live_rig(str(uri), study, env) as rig, served(study, env=env) as url:
            yield Robot(study, str(uri), url, rig)


def until(condition: Callable[[], object], what: str, deadline_s: float = LIVE_DEADLINE_S) -> object:
    """Poll `condition` until it is true (returned), failing after `deadline_s` seconds."""
    deadline = time.monotonic() + deadline_s
    while not (value := condition()):
        assert time.monotonic() < deadline, f"no {what} within {deadline_s:g} s"
        time.sleep(0.1)
    return value


def live_state(driver) -> str | None:
    """The run page's live state as shown now (None while the page reloads)."""
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.common.by import By

    try:
        return driver.find_element(By.ID, "live-state").text
    except WebDriverException:
        return None


def watch(driver, wanted: tuple[str, ...], seen: list[str]) -> str:
    """Wait until the run page shows one of the `wanted` states, noting every state shown on the way in `seen`; a run
    that ends otherwise fails at once, with its reason."""
    from selenium.webdriver.common.by import By

    def reached() -> str | None:
        state = live_state(driver)
        if state and (not seen or seen[-1] != state):
            seen.append(state)
        if state in (*ENDINGS, "aborted") and state not in wanted:
            pytest.fail(f"the live run ended {state} ({driver.find_element(By.ID, 'live-detail').text}) while {' or '.join(wanted)} was awaited")
        return state if state in wanted else None

    return str(until(reached, f"live state {' or '.join(wanted)} (seen: {seen})"))


def robot_table(study: Path, **keys: str) -> None:
    """Add keys to the [robot] table of study.toml (read by the next `trials run --robot`)."""
    text = (study / "study.toml").read_text()
    head, uri, tail = re.split(r'(\[robot\]\nuri = "[^"]+"\n)', text)
    (study / "study.toml").write_text(head + uri + "".join(f"{k} = {v}\n" for k, v in keys.items()) + tail)


def test_start_drives_a_run_live_and_the_page_follows_it_to_its_end(robot):
    from selenium.webdriver.common.by import By

    code = rows(robot.study / "plan.csv")[0]["run_code"]
    seen: list[str] = []
    with browser() as driver:
        driver.get(robot.url)
        driver.get(robot.url.split("?")[0] + f"runs/{code}")
        assert live_state(driver) == "not started"
        go(driver, By.ID, "start")
        pages = [driver.page_source]
        watch(driver, ("driving",), seen)
        pages.append(driver.page_source)
        ending = watch(driver, ENDINGS, seen)
        until(lambda: "Driven live by the toolkit." in driver.page_source, "reloaded page with the outcome")
        pages += [driver.page_source, driver.execute_script("return document.body.innerText")]
        assert 'id="estop"' not in driver.page_source and f"Outcome: {ending}" in driver.find_element(By.TAG_NAME, "body").text
        driver.get(robot.url.split("?")[0])
        pages.append(driver.page_source)
    assert seen[0] in ("starting", "waiting for sensors", "driving") and seen[-2:] == ["driving", ending]
    [outcome] = [row for row in rows(robot.study / "outcomes.csv") if row["run_code"] == code]
    assert (outcome["status"], outcome["perception"]) == (ending, "live") and "controller" not in outcome
    assert [(e["event"], e["detail"]) for e in rows(robot.study / "run_events.csv") if e["run_code"] == code] == [
        ("start", f"driven live on {robot.uri}"), ("finish", "")]
    assert (robot.study / "runs" / f"{code}.mcap").stat().st_size > 10_000
    assert not [page for page in pages if NAMES.search(page.encode())]


def test_estop_stops_the_robot_and_keeps_the_aborted_runs_log(robot):
    from selenium.webdriver.common.by import By

    robot_table(robot.study, goal="[40.0, 0.0]", timeout="120.0")  # a long run, so that E-STOP lands while it drives
    code = rows(robot.study / "plan.csv")[1]["run_code"]
    seen: list[str] = []
    with browser() as driver:
        driver.get(robot.url)
        driver.get(robot.url.split("?")[0] + f"runs/{code}")
        go(driver, By.ID, "start")
        watch(driver, ("driving",), seen)
        go(driver, By.ID, "estop")
        watch(driver, ("aborted",), seen)
        detail = driver.find_element(By.ID, "live-detail").text
        until(lambda: 'name="event" value="start"' not in driver.page_source and "Start run" in driver.page_source and
              'id="estop"' not in driver.page_source, "the page of the aborted run, ready to start again")
        page = driver.page_source
    assert detail in ("e-stop from the console", "stopped by SIGTERM (Ctrl-C or kill of trials run, or the console's stop)")
    [*_, start, abort] = [(e["event"], e["detail"]) for e in rows(robot.study / "run_events.csv") if e["run_code"] == code]
    assert start[0] == "start" and abort[0] == "abort" and abort[1].startswith(f"run {code} aborted: {detail}; its log is ")
    [kept] = (robot.study / "runs" / "aborted").glob(f"{code}-*.mcap")
    assert kept.stat().st_size > 1000 and str(kept) in abort[1]
    assert code not in [row["run_code"] for row in rows(robot.study / "outcomes.csv")]
    # The last command the robot received, and the last one a witness on /cmd_vel heard: stand still (each process
    # writes what it received on its own time, so they are polled).
    until(lambda: [float(v) for v in robot.rig.commands.read_text().splitlines()[-1].split(",")[1:]] == [0.0, 0.0],
          "zero as the robot's last command", 30)
    until(lambda: robot.rig.last_heard() == (0.0, 0.0), "zero as the last command the witness heard", 30)
    assert not NAMES.search(page.encode())
