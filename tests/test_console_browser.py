"""The field day end to end in real browsers (Debian's Chromium through Selenium): `trials serve` on a
blinded study, two runs worked through by the experimenter with the sample bag attached (uploaded, then
by path), scored, and judged by three participants from their own browsers; then `trials report
--unblind` with no other command in between. The files left are those the command line leaves.

A blinded field day that cannot quietly go wrong: served on every address, the questionnaire reached from the
QR code's link as soon as the run is finished, the logs played in the background, a corrected log, and the
commands an experimenter might try on the way (an early unblinding, a plain `trials run`, a stale report), with
no arm compared on any page until the study is unblinded.

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
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.support.blinding import NAMES
from tests.support.console import PHONE, WINDOW, browser, design_study, field_day, go, need_chromium, served
from tests.support.live_rig import Rig
from tests.support.registration import recorded_digest
from trials.cli import main

pytestmark = pytest.mark.slow


@pytest.fixture(autouse=True)
def _chromium() -> None:
    need_chromium()


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
    commitment = recorded_digest(study)  # as `trials design` printed it
    assert main(["report", "--study", str(study), "--unblind", "--commitment", commitment]) == 0
    arms = json.loads((study / "sealed" / "allocation.json").read_text())["arms"]
    plan = rows(study / "plan.csv")
    codes = [row["run_code"] for row in plan]
    record = json.loads((study / "report" / "report.json").read_text())
    assert [record["scores"][row["run_code"]]["arm"] for row in plan] == [arms[row["Controller"]] for row in plan]
    # Both logs were attached: the toolkit drove neither robot, so no judgment or score is credited to a controller.
    assert record["runs"]["made"] == {"simulated": 0, "driven live": 0, "software robot": 0, "external log": 2}
    assert record["runs"]["left_out_of_comparisons"] == codes and record["table_ii"] == [] and record["fits"] == []
    markdown = (study / "report" / "report.md").read_text()
    assert (f"2 runs ({codes[0]}, {codes[1]}) were played from an external robot log: the toolkit did not drive those robots, so their "
            "6 judgment(s) and 2 human score(s) are not credited to a controller") in markdown
    assert "No judgments of runs the toolkit drove yet" in markdown
    assert json.loads((study / "unblinding.json").read_text())["unblinded_utc"]


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
    from tests.support.live_rig import live_rig, repository_env, set_robot_keys
    from tests.support.ros1_echo import environment
    from tests.support.ros1_master import master_process

    root = tmp_path_factory.mktemp("live")
    with master_process(root / "ros") as (uri, _):
        study = root / "study"
        assert main(["design", "--ab", "--robot", str(uri), "--study", str(study), "--quiet"]) == 0
        # A loaded machine delivers scans late now and then: a longer watchdog and sensor wait than a robot's keep
        # these runs from stopping for that (tests/test_robot_live_ros1.py tests the stop rules themselves).
        set_robot_keys(study, watchdog="2.0", sensor_wait="60.0", goal_frame="\"odom\"")
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
        until(lambda: "Driven live by the toolkit on the software robot" in driver.page_source, "reloaded page with the outcome")
        pages += [driver.page_source, driver.execute_script("return document.body.innerText")]
        assert 'id="estop"' not in driver.page_source and f"Outcome: {ending}" in driver.find_element(By.TAG_NAME, "body").text
        driver.get(robot.url.split("?")[0])
        pages.append(driver.page_source)
    assert seen[0] in ("starting", "waiting for sensors", "driving") and seen[-2:] == ["driving", ending]
    [outcome] = [row for row in rows(robot.study / "outcomes.csv") if row["run_code"] == code]
    assert (outcome["status"], outcome["perception"]) == (ending, "software-robot") and "controller" not in outcome
    assert [(e["event"], e["detail"]) for e in rows(robot.study / "run_events.csv") if e["run_code"] == code] == [
        ("start", f"driven live on {robot.uri}"), ("finish", "")]
    assert (robot.study / "runs" / f"{code}.mcap").stat().st_size > 10_000
    assert not [page for page in pages if NAMES.search(page.encode())]


def test_estop_stops_the_robot_and_keeps_the_aborted_runs_log(robot):
    from selenium.webdriver.common.by import By

    from tests.support.live_rig import set_robot_keys

    set_robot_keys(robot.study, goal="[40.0, 0.0]", timeout="120.0")  # a long run, so that E-STOP lands while it drives
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
    assert detail == "e-stop from the console"  # the console creates runs/estop before it signals `trials run`
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


# --- a blinded field day that cannot quietly go wrong (issue 38) -----------------------------------------------------

#: Central European time, without the zone database, for the console's local times.
CENTRAL_EUROPE = "CET-1CEST,M3.5.0,M10.5.0/3"
#: What no page may show of a blinded study before it is unblinded: an arm comparison (Table II, shares, differences, p-values).
COMPARISONS = re.compile(r'id="table-ii"|Table II|\d+%|Holm|points|Share of|−')


@dataclass
class Walk:
    """What a blinded field day through the console left: the study, what `trials serve` printed after its link, the
    pages seen (title, URL, source) before and after its unblinding, the participant's link and QR code, the commands
    tried on the way (name -> exit code, stdout, stderr) and the files as they were at each step that matters."""

    study: Path
    codes: list[str]
    printed: list[str] = field(default_factory=list)
    pages: list[str] = field(default_factory=list)
    unblinded_pages: list[str] = field(default_factory=list)
    link: str = ""
    qr: str = ""
    commands: dict[str, tuple[int, str, str]] = field(default_factory=dict)
    saw_playing: list[str] = field(default_factory=list)
    questionnaire_before_log: str = ""
    outcomes_after_refused_run: list[dict[str, str]] = field(default_factory=list)
    runs_after_refused_run: list[str] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)


def command(walk: Walk, name: str, *argv: str) -> int:
    """Run `trials ARGV` in this process, as from a terminal, keeping what it printed under `name`."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([*argv, "--study", str(walk.study)])
    walk.commands[name] = (code, out.getvalue(), err.getvalue())
    return code


def modules(svg: str) -> str:
    """A QR code's modules, the outline of its one SVG path (the browser writes the element back its own way)."""
    return re.search(r'\sd="([^"]+)"', svg).group(1)


def own_address(host: str) -> bool:
    """Whether `host` is loopback or an address of this machine (it binds; nothing is sent), so a browser here may open it."""
    import socket

    from trials.console.address import is_loopback

    if is_loopback(host):
        return True
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as own:
            own.bind((host, 0))
        return True
    except OSError:
        return False


def opened(link: str) -> str:
    """The URL a phone here opens for a participant's link: the link itself when it points at this machine (the test
    sends nothing elsewhere), else the same page through loopback."""
    host = link.split("/")[2].rsplit(":", 1)[0]
    return link if own_address(host) else link.replace(host, "127.0.0.1", 1)


@pytest.fixture(scope="module")
def walk(tmp_path_factory, robot_logs_dir) -> Walk:
    """A blinded two-run field day in the console served on every address (--host 0.0.0.0), with the commands an
    experimenter might try on the way: run 1 finished, its questionnaire answered from its QR code's link before its
    log is attached, its log attached (upload) and played; `trials report --unblind` too early (refused); plain `trials
    run` (refused: a field study simulates nothing); a blinded report; run 2 finished and its log attached by path (the
    report is now older than the data); run 1's log corrected; the other answers; then the unblinding, after which
    the pages are seen again."""
    import os

    import segno
    from selenium.webdriver.common.by import By

    from tests.support.console import played

    study = design_study(tmp_path_factory.mktemp("field-day-38") / "study")
    log = robot_logs_dir / "stationary_ros1.bag"
    codes = [r["run_code"] for r in rows(study / "plan.csv")]
    walk = Walk(study, codes)
    commitment = recorded_digest(study)

    with served(study, "--host", "0.0.0.0", env={**os.environ, "TZ": CENTRAL_EUROPE}, printed=walk.printed) as url, browser() as experimenter:
        base = url.split("?")[0]

        def seen(driver, into: list[str] | None = None) -> str:
            page = driver.title + "\n" + driver.current_url + "\n" + driver.page_source
            (walk.pages if into is None else into).append(page)
            return page

        def attach(code: str, by: str, value: str, start: str, duration: str, correction: bool = False) -> None:
            kind = "fix" if correction else "log"
            experimenter.find_element(By.ID, f"{kind}-{by}").send_keys(value)
            experimenter.find_element(By.ID, f"{kind}-start").send_keys(start)
            experimenter.find_element(By.ID, f"{kind}-duration").send_keys(duration)
            go(experimenter, By.ID, "replace-log" if correction else "attach")
            page = seen(experimenter)
            if 'id="playing"' in page:
                walk.saw_playing.append(code)
            played(experimenter)
            seen(experimenter)

        experimenter.get(url)
        seen(experimenter)
        first, second = codes
        experimenter.get(base + f"runs/{first}")
        go(experimenter, By.ID, "start")
        go(experimenter, By.ID, "finish")
        seen(experimenter)
        walk.link = experimenter.find_element(By.ID, "participant-link").get_attribute("href")
        walk.qr = experimenter.find_element(By.CSS_SELECTOR, "div.qr").get_attribute("innerHTML").strip()
        # The code encodes the link shown: its modules (the path's outline) are those segno draws for that link.
        assert modules(walk.qr) == modules(segno.make(walk.link, error="m").svg_inline(scale=4))
        with browser(PHONE) as phone:
            phone.get(opened(walk.link))
            walk.questionnaire_before_log = phone.page_source
            phone.find_element(By.ID, "participant").send_keys("P01")
            phone.find_element(By.ID, "compliant-yes").click()
            go(phone, By.ID, "send")
            seen(phone)

            attach(first, "file", str(log), "15", "6")
            walk.figures = [row.text for row in experimenter.find_elements(By.CSS_SELECTOR, "table.figures tr")]

            command(walk, "early unblinding", "report", "--unblind", "--commitment", commitment)
            experimenter.refresh()
            seen(experimenter)
            command(walk, "plain run", "run")
            walk.outcomes_after_refused_run = rows(study / "outcomes.csv")
            walk.runs_after_refused_run = sorted(p.name for p in (study / "runs").iterdir())
            command(walk, "blinded report", "report")
            command(walk, "status when current", "status")

            experimenter.get(base + f"runs/{second}")
            go(experimenter, By.ID, "start")
            experimenter.find_element(By.ID, "note").send_keys("two people walked past")
            go(experimenter, By.ID, "add-note")
            go(experimenter, By.ID, "finish")
            attach(second, "path", str(log), "15", "6")
            command(walk, "status when stale", "status")

            experimenter.get(base + f"runs/{first}")
            experimenter.find_element(By.CSS_SELECTOR, "#correct summary").click()
            attach(first, "file", str(log), "10", "5", correction=True)

            experimenter.get(base + f"runs/{second}")
            phone.get(opened(experimenter.find_element(By.ID, "participant-link").get_attribute("href")))
            phone.find_element(By.ID, "compliant-no").click()
            go(phone, By.ID, "send")
            seen(phone)
        for path in ("", "progress", f"runs/{first}", f"runs/{second}", f"runs/{first}/score"):
            experimenter.get(base + path)
            seen(experimenter)

        command(walk, "unblinding", "report", "--unblind", "--commitment", commitment)
        for path in ("", "progress", f"runs/{first}", f"runs/{first}/score"):
            experimenter.get(base + path)
            seen(experimenter, walk.unblinded_pages)
    return walk


def header(page: str) -> str:
    found = re.search(r'id="blinding">(.*?)</span>', page, re.S)
    return found.group(1) if found else ""


def test_the_questionnaire_opens_from_its_qr_code_at_the_network_address_as_the_run_finishes(walk):
    from trials.console.address import network_address

    own = network_address()
    host = walk.link.split("/")[2].rsplit(":", 1)[0]
    assert host == (own if own is not None else "127.0.0.1")  # none found: the address the experimenter's browser used
    assert re.fullmatch(rf"http://{re.escape(host)}:\d+/q/[0-9a-f]{{24}}", walk.link)
    origin = walk.link.rsplit("/q/", 1)[0]
    assert walk.printed[1] == (f"Participants' links and QR codes carry {origin}, this machine's address on the network." if own is not None else
                               "No network address of this machine was found: participants' links carry the address the experimenter's browser opened.")
    assert "The robot has finished this run." in walk.questionnaire_before_log and 'id="send"' in walk.questionnaire_before_log
    first, second = walk.codes
    answers = [(r["run_code"], r["participant"], r["compliant"]) for r in rows(walk.study / "responses.csv")]
    assert answers == [(first, "P01", "yes"), (second, "P01", "no")]
    if own is not None:
        assert any(f"at this laptop's address {own}" in page for page in walk.pages)


def test_an_early_unblinding_is_refused_and_the_console_stays_blinded(walk):
    code, _, err = walk.commands["early unblinding"]
    assert code == 2 and "only 1 of 2 runs finished: opening the key now would be an interim look" in err
    experimenter_pages = [page for page in walk.pages if 'id="blinding"' in page]
    assert len(experimenter_pages) > 10 and {header(page) for page in experimenter_pages} == {"field-day · blinded"}
    [opening] = json.loads((walk.study / "unblinding.json").read_text())["openings"]  # the final one only
    assert (opening["completeness"], opening["interim"]) == ("2 of 2 runs finished", None)


def test_plain_trials_run_in_the_field_study_is_refused_and_simulates_nothing(walk):
    first, second = walk.codes
    code, _, err = walk.commands["plain run"]
    assert code == 2 and "is a field study" in err and f"refusing to simulate run {second}" in err
    assert [(r["run_code"], r["perception"]) for r in walk.outcomes_after_refused_run] == [(first, "log")]
    assert walk.runs_after_refused_run == [f"{first}.mcap"]


def test_trials_status_says_when_the_report_is_older_than_the_data(walk):
    assert walk.commands["blinded report"][0] == 0
    code, out, _ = walk.commands["status when current"]
    assert code == 0 and "report: up to date with the data" in out
    code, out, _ = walk.commands["status when stale"]
    assert code == 0 and "report: older than the data: run `trials report` again" in out


def test_logs_are_played_in_the_background_and_the_run_page_shows_the_run(walk):
    first, second = walk.codes
    assert walk.saw_playing == [first, second, first]
    assert any("Checking and playing the log..." in page for page in walk.pages)
    old = rows(next((walk.study / "superseded").iterdir()) / "outcomes.csv")[0]
    assert walk.figures == ["Status " + old["status"], f"Duration {float(old['duration_s']):.1f} s", "Time to goal -",
                            f"Path length {float(old['path_length_m']):.2f} m", f"Closest gap {float(old['min_distance_m']):.2f} m",
                            f"Within 0.5 m {float(old['time_within_0_5m_s']):.1f} s", f"Within 1.2 m {float(old['time_within_1_2m_s']):.1f} s",
                            "Collisions 0", walk.figures[-1]]
    assert re.fullmatch(r"Finished \d{4}-\d\d-\d\d \d\d:\d\d CES?T", walk.figures[-1])  # the laptop's zone, not UTC


def test_a_corrected_log_replaces_the_run_and_the_earlier_is_kept_aside(walk):
    first, second = walk.codes
    [kept] = (walk.study / "superseded").iterdir()
    [old] = rows(kept / "outcomes.csv")
    new = next(r for r in rows(walk.study / "outcomes.csv") if r["run_code"] == first)
    assert old["run_code"] == first and float(new["duration_s"]) < float(old["duration_s"]) - 0.5  # 6 s of the bag, then 5 s
    assert (kept / "runs" / f"{first}.mcap").stat().st_size > 10_000 and (kept / "logs" / f"{first}.bag").exists()
    assert (walk.study / "sealed" / "superseded" / kept.name / "runs" / f"{first}.json.gz").exists()
    assert [(e["event"], e["detail"]) for e in rows(walk.study / "run_events.csv") if e["run_code"] == first] == [
        ("start", ""), ("finish", ""), ("log", f"logs/{first}.bag"),
        ("note", f"log corrected: the earlier run log, outcome row and upload are kept in superseded/{kept.name}/"), ("log", f"logs/{first}.bag")]


def test_no_page_compared_the_arms_or_named_a_controller_before_unblinding(walk):
    compared = [page.splitlines()[:2] for page in walk.pages if COMPARISONS.search(page)]
    named = [page.splitlines()[:2] for page in walk.pages if NAMES.search(page.encode())]
    assert compared == [] and named == []
    progress = [page for page in walk.pages if "<h1>Progress</h1>" in page]
    assert progress and all("compares no arms" in page for page in progress)


def test_after_unblinding_every_page_says_since_when(walk):
    from datetime import datetime
    from zoneinfo import ZoneInfo

    assert walk.commands["unblinding"][0] == 0
    [opened] = json.loads((walk.study / "unblinding.json").read_text())["unblinded_utc"]
    local = datetime.fromisoformat(opened).astimezone(ZoneInfo("Europe/Berlin"))
    assert {header(page) for page in walk.unblinded_pages} == {f"field-day · unblinded on {local:%Y-%m-%d %H:%M %Z}"}
    [progress] = [page for page in walk.unblinded_pages if "<h1>Progress</h1>" in page]
    assert "Table II so far" in progress and "compares no arms" not in progress
